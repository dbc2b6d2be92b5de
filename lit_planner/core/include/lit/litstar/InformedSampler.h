#pragma once
/** \file litstar/InformedSampler.h
 *  \brief Seeded direct informed sampling for path length in R^n: uniform in the bounds intersected with the
 *  prolate hyperspheroid {x : |x - start| + |x - goal| <= c}. Owning its RNG makes LIT* deterministic per
 *  seed even when several planners run in one process (OMPL's global seed can be set only once). */

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

        /** \brief Sets the foci: one start and one or more goals (several goals: rejection sampling). */
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
        void sampleEllipsoid(double maxCost, double *x);

        ompl::base::SpaceInformationPtr si_;
        unsigned int dim_;
        std::vector<double> lower_, upper_;
        double spaceMeasure_;
        Eigen::VectorXd start_;
        std::vector<Eigen::VectorXd> goals_;
        Eigen::VectorXd centre_;
        /** \brief Householder reflection mapping e_1 onto the transverse axis. */
        Eigen::MatrixXd rotation_;
        double minimumCost_{0.0};
        ompl::RNG rng_;
    };
}  // namespace lit::litstar
