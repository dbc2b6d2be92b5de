#pragma once
/** \file litstar/InformedSampler.h
 *  \brief Seeded direct informed sampling for path length in R^n: uniform in the bounds intersected with the
 *  prolate hyperspheroid {x : |x - start| + |x - goal| <= c}; with several goals, uniform in the union of their
 *  hyperspheroids (one picked in proportion to its measure, a draw kept with probability 1 / the number of them
 *  that hold it). Owning its RNG makes LIT* deterministic per seed even when several planners run in one process
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

        /** \brief Sets the foci: one start and one or more goals. */
        void setFoci(const std::vector<double> &start, const std::vector<std::vector<double>> &goals);

        /** \brief Draws a state uniformly from the informed set of \e maxCost (the whole space when infinite).
         *  Returns false after \e maxAttempts rejections. */
        bool sample(double maxCost, ompl::base::State *state, unsigned int maxAttempts = 10000u);

        /** \brief Straight-line heuristic |x - start| + min_g |x - g|. */
        double heuristicCost(const double *x) const;

        /** \brief Minimum possible cost (straight line start to nearest goal). */
        double minimumCost() const
        {
            return minimumCost_;
        }

    private:
        bool sampleUniform(double *x);
        /** \brief Uniform in the hyperspheroid of goal \e index (foci start and that goal). */
        void sampleEllipsoid(std::size_t index, double maxCost, double *x);
        /** \brief A uniform draw from the union of the goals' hyperspheroids of \e maxCost (several goals);
         *  false when the draw is rejected (a point that more hyperspheroids hold is kept less often). */
        bool sampleUnion(double maxCost, double *x);

        ompl::base::SpaceInformationPtr si_;
        unsigned int dim_;
        std::vector<double> lower_, upper_;
        double spaceMeasure_;
        Eigen::VectorXd start_;
        std::vector<Eigen::VectorXd> goals_;
        double minimumCost_{0.0};
        /** \brief Per goal: its distance from the start, the centre of its hyperspheroid and the Householder
         *  reflection mapping e_1 onto its transverse axis. */
        std::vector<double> goalCosts_;
        std::vector<Eigen::VectorXd> goalCentres_;
        std::vector<Eigen::MatrixXd> goalRotations_;
        /** \brief The per-goal measures of the last union draw's cost, cumulated (several goals). */
        double unionCost_{-1.0};
        std::vector<double> cumulativeMeasures_;
        ompl::RNG rng_;
    };
}  // namespace lit::litstar
