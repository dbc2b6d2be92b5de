#pragma once
/** \file litstar/InformedSampler.h
 *  \brief Seeded direct informed sampling for path length in R^n: uniform in the bounds intersected with the
 *  prolate hyperspheroid {x : |x - start| + |x - goal| <= c}; with several starts or goals, uniform in the union of
 *  the hyperspheroids of every start-goal pair (one picked in proportion to its measure, a draw kept with
 *  probability 1 / the number of them that hold it). Owning its RNG makes LIT* deterministic per seed even when several planners run in one process
 *  (OMPL's global seed can be set only once). */

#include <ompl/base/SpaceInformation.h>
#include <ompl/util/RandomNumbers.h>

#include <Eigen/Dense>

#include <cstdint>
#include <vector>

namespace lit::litstar
{
    class InformedSampler
    {
    public:
        /** \brief Sampler over \e si's R^n bounds with its own RNG seeded by \e seed. */
        InformedSampler(const ompl::base::SpaceInformationPtr &si, std::uint_fast32_t seed);

        /** \brief Sets the foci: one or more starts and one or more goals. */
        void setFoci(const std::vector<std::vector<double>> &starts, const std::vector<std::vector<double>> &goals);
        /** \brief Sets the foci: one start and one or more goals. */
        void setFoci(const std::vector<double> &start, const std::vector<std::vector<double>> &goals)
        {
            setFoci(std::vector<std::vector<double>>{start}, goals);
        }

        /** \brief Draws a state uniformly from the informed set of \e maxCost (the whole space when infinite).
         *  Returns false after \e maxAttempts rejections. */
        bool sample(double maxCost, ompl::base::State *state, unsigned int maxAttempts = 10000u);

        /** \brief Straight-line heuristic min_s |x - s| + min_g |x - g|. */
        double heuristicCost(const double *x) const;

        /** \brief Minimum possible cost (the straight line of the nearest start-goal pair). */
        double minimumCost() const
        {
            return minimumCost_;
        }

    private:
        bool sampleUniform(double *x);
        /** \brief Uniform in the hyperspheroid of start-goal pair \e index. */
        void sampleEllipsoid(std::size_t index, double maxCost, double *x);
        /** \brief A uniform draw from the union of the pairs' hyperspheroids of \e maxCost (several pairs);
         *  false when the draw is rejected (a point that more hyperspheroids hold is kept less often). */
        bool sampleUnion(double maxCost, double *x);

        ompl::base::SpaceInformationPtr si_;
        unsigned int dim_;
        std::vector<double> lower_, upper_;
        double spaceMeasure_;
        std::vector<Eigen::VectorXd> starts_;
        std::vector<Eigen::VectorXd> goals_;
        double minimumCost_{0.0};
        /** \brief Per start-goal pair (start-major): its foci, their distance, the centre of its hyperspheroid
         *  and the Householder reflection H = I - u u^T mapping e_1 onto its transverse axis, as u (scaled so
         *  that |u|^2 = 2; zero for H = I): O(n) per draw and O(pairs n) memory. With several starts and 200
         *  goals the n x n matrices took 41 MB in R^16 and O(n^2) per draw. */
        std::vector<std::size_t> pairStarts_, pairGoals_;
        std::vector<double> pairCosts_;
        std::vector<Eigen::VectorXd> pairCentres_;
        std::vector<Eigen::VectorXd> pairReflections_;
        /** \brief The one pair's reflection as a matrix (one start and one goal: the draws stay bit-identical to
         *  those every benchmark of this project was measured with). */
        Eigen::MatrixXd singleRotation_;
        /** \brief Scratch of the union draw: the distances of the draw to each start and each goal. */
        std::vector<double> toStarts_, toGoals_;
        /** \brief The per-pair measures of the last union draw's cost, cumulated (several pairs). */
        double unionCost_{-1.0};
        std::vector<double> cumulativeMeasures_;
        ompl::RNG rng_;
    };
}  // namespace lit::litstar
