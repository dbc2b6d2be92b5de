#include "lit/litstar/InformedSampler.h"

#include "lit/InformedMeasure.h"

#include <ompl/base/spaces/RealVectorStateSpace.h>

#include <cmath>
#include <limits>

namespace lit::litstar
{
    InformedSampler::InformedSampler(const ompl::base::SpaceInformationPtr &si, std::uint_fast32_t seed)
      : si_(si), dim_(si->getStateDimension()), rng_(seed)
    {
        const auto &bounds = si->getStateSpace()->as<ompl::base::RealVectorStateSpace>()->getBounds();
        lower_ = bounds.low;
        upper_ = bounds.high;
        spaceMeasure_ = si->getSpaceMeasure();
    }

    void InformedSampler::setFoci(const std::vector<double> &start, const std::vector<std::vector<double>> &goals)
    {
        start_ = Eigen::Map<const Eigen::VectorXd>(start.data(), dim_);
        goals_.clear();
        minimumCost_ = std::numeric_limits<double>::infinity();
        for (const auto &goal : goals)
        {
            goals_.emplace_back(Eigen::Map<const Eigen::VectorXd>(goal.data(), dim_));
            minimumCost_ = std::min(minimumCost_, (goals_.back() - start_).norm());
        }
        rotation_ = Eigen::MatrixXd::Identity(dim_, dim_);
        if (goals_.size() == 1u)
        {
            centre_ = 0.5 * (start_ + goals_.front());
            const Eigen::VectorXd axis = (goals_.front() - start_) / std::max(minimumCost_, 1e-300);
            Eigen::VectorXd v = Eigen::VectorXd::Unit(dim_, 0) - axis;
            if (v.norm() > 1e-12)
                rotation_ -= 2.0 * v * v.transpose() / v.squaredNorm();
        }
    }

    double InformedSampler::heuristicCost(const double *x) const
    {
        const Eigen::Map<const Eigen::VectorXd> p(x, dim_);
        double toGoal = std::numeric_limits<double>::infinity();
        for (const auto &goal : goals_)
            toGoal = std::min(toGoal, (goal - p).norm());
        return (p - start_).norm() + toGoal;
    }

    bool InformedSampler::sampleUniform(double *x)
    {
        for (unsigned int i = 0; i < dim_; ++i)
            x[i] = rng_.uniformReal(lower_[i], upper_[i]);
        return true;
    }

    void InformedSampler::sampleEllipsoid(double maxCost, double *x)
    {
        Eigen::VectorXd ball(dim_);
        for (unsigned int i = 0; i < dim_; ++i)
            ball[i] = rng_.gaussian01();
        const double radius = std::pow(rng_.uniform01(), 1.0 / static_cast<double>(dim_));
        ball *= radius / std::max(ball.norm(), 1e-300);
        const double transverse = 0.5 * maxCost;
        const double conjugate = 0.5 * std::sqrt(std::max(maxCost * maxCost - minimumCost_ * minimumCost_, 0.0));
        ball[0] *= transverse;
        for (unsigned int i = 1; i < dim_; ++i)
            ball[i] *= conjugate;
        Eigen::Map<Eigen::VectorXd>(x, dim_) = rotation_ * ball + centre_;
    }

    bool InformedSampler::sample(double maxCost, ompl::base::State *state, unsigned int maxAttempts)
    {
        double *x = state->as<ompl::base::RealVectorStateSpace::StateType>()->values;
        const bool useEllipsoid = goals_.size() == 1u && std::isfinite(maxCost) &&
                                  informedMeasure(dim_, maxCost, minimumCost_, spaceMeasure_) < spaceMeasure_;
        for (unsigned int attempt = 0; attempt < maxAttempts; ++attempt)
        {
            if (useEllipsoid)
            {
                sampleEllipsoid(maxCost, x);
                if (si_->satisfiesBounds(state))
                    return true;
            }
            else
            {
                sampleUniform(x);
                if (!std::isfinite(maxCost) || heuristicCost(x) <= maxCost)
                    return true;
            }
        }
        return false;
    }
}  // namespace lit::litstar
