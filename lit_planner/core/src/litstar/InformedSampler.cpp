#include "lit/litstar/InformedSampler.h"

#include "lit/InformedMeasure.h"

#include <ompl/base/spaces/RealVectorStateSpace.h>

#include <algorithm>
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

    void InformedSampler::setFoci(const std::vector<std::vector<double>> &starts,
                                  const std::vector<std::vector<double>> &goals)
    {
        starts_.clear();
        goals_.clear();
        for (const auto &coordinates : starts)
            starts_.emplace_back(Eigen::Map<const Eigen::VectorXd>(coordinates.data(), dim_));
        for (const auto &coordinates : goals)
            goals_.emplace_back(Eigen::Map<const Eigen::VectorXd>(coordinates.data(), dim_));
        pairStarts_.clear();
        pairGoals_.clear();
        pairCosts_.clear();
        pairCentres_.clear();
        pairReflections_.clear();
        unionCost_ = -1.0;
        minimumCost_ = std::numeric_limits<double>::infinity();
        for (std::size_t s = 0; s < starts_.size(); ++s)
            for (std::size_t g = 0; g < goals_.size(); ++g)
            {
                const Eigen::VectorXd &start = starts_[s], &goal = goals_[g];
                const double cost = (goal - start).norm();
                minimumCost_ = std::min(minimumCost_, cost);
                // The Householder reflection mapping e_1 onto the transverse axis start -> goal.
                const Eigen::VectorXd axis = (goal - start) / std::max(cost, 1e-300);
                Eigen::VectorXd v = Eigen::VectorXd::Unit(dim_, 0) - axis;
                if (v.norm() > 1e-12)
                {
                    if (starts_.size() * goals_.size() == 1u)
                    {
                        singleRotation_ = Eigen::MatrixXd::Identity(dim_, dim_);
                        singleRotation_ -= 2.0 * v * v.transpose() / v.squaredNorm();
                    }
                    v *= std::sqrt(2.0) / v.norm();
                }
                else
                {
                    if (starts_.size() * goals_.size() == 1u)
                        singleRotation_ = Eigen::MatrixXd::Identity(dim_, dim_);
                    v.setZero();
                }
                pairStarts_.push_back(s);
                pairGoals_.push_back(g);
                pairCosts_.push_back(cost);
                pairCentres_.push_back(0.5 * (start + goal));
                pairReflections_.push_back(std::move(v));
            }
        toStarts_.assign(starts_.size(), 0.0);
        toGoals_.assign(goals_.size(), 0.0);
    }

    double InformedSampler::heuristicCost(const double *x) const
    {
        const Eigen::Map<const Eigen::VectorXd> p(x, dim_);
        double fromStart = std::numeric_limits<double>::infinity();
        for (const auto &start : starts_)
            fromStart = std::min(fromStart, (p - start).norm());
        double toGoal = std::numeric_limits<double>::infinity();
        for (const auto &goal : goals_)
            toGoal = std::min(toGoal, (goal - p).norm());
        return fromStart + toGoal;
    }

    bool InformedSampler::sampleUniform(double *x)
    {
        for (unsigned int i = 0; i < dim_; ++i)
            x[i] = rng_.uniformReal(lower_[i], upper_[i]);
        return true;
    }

    void InformedSampler::sampleEllipsoid(std::size_t index, double maxCost, double *x)
    {
        Eigen::VectorXd ball(dim_);
        for (unsigned int i = 0; i < dim_; ++i)
            ball[i] = rng_.gaussian01();
        const double radius = std::pow(rng_.uniform01(), 1.0 / static_cast<double>(dim_));
        ball *= radius / std::max(ball.norm(), 1e-300);
        const double cost = pairCosts_[index];
        ball[0] *= 0.5 * maxCost;
        const double conjugate = 0.5 * std::sqrt(std::max(maxCost * maxCost - cost * cost, 0.0));
        for (unsigned int i = 1; i < dim_; ++i)
            ball[i] *= conjugate;
        if (pairCosts_.size() == 1u)
            Eigen::Map<Eigen::VectorXd>(x, dim_) = singleRotation_ * ball + pairCentres_[index];
        else
        {
            const Eigen::VectorXd &u = pairReflections_[index];
            Eigen::Map<Eigen::VectorXd>(x, dim_) = ball - u * u.dot(ball) + pairCentres_[index];
        }
    }

    bool InformedSampler::sampleUnion(double maxCost, double *x)
    {
        const double pick = rng_.uniform01() * cumulativeMeasures_.back();
        const std::size_t index = static_cast<std::size_t>(
            std::upper_bound(cumulativeMeasures_.begin(), cumulativeMeasures_.end(), pick) -
            cumulativeMeasures_.begin());
        const std::size_t chosen = std::min(index, pairCosts_.size() - 1u);
        sampleEllipsoid(chosen, maxCost, x);
        // Kept with probability 1 / (the hyperspheroids holding it): uniform over the union.
        // Each distance once: O((starts + goals) n + pairs), not O(pairs n).
        const Eigen::Map<const Eigen::VectorXd> p(x, dim_);
        for (std::size_t i = 0; i < starts_.size(); ++i)
            toStarts_[i] = (p - starts_[i]).norm();
        for (std::size_t i = 0; i < goals_.size(); ++i)
            toGoals_[i] = (goals_[i] - p).norm();
        std::size_t holding = 1u;  // the chosen one, also where rounding puts x just outside it
        for (std::size_t j = 0; j < pairCosts_.size(); ++j)
            if (j != chosen && toStarts_[pairStarts_[j]] + toGoals_[pairGoals_[j]] <= maxCost)
                ++holding;
        return holding == 1u || rng_.uniform01() * static_cast<double>(holding) < 1.0;
    }

    bool InformedSampler::sample(double maxCost, ompl::base::State *state, unsigned int maxAttempts)
    {
        double *x = state->as<ompl::base::RealVectorStateSpace::StateType>()->values;
        const bool useEllipsoid = pairCosts_.size() == 1u && std::isfinite(maxCost) &&
                                  informedMeasure(dim_, maxCost, minimumCost_, spaceMeasure_) < spaceMeasure_;
        bool useUnion = false;
        if (pairCosts_.size() > 1u && std::isfinite(maxCost))
        {
            if (maxCost != unionCost_)
            {
                // Each goal's hyperspheroid in proportion to its measure (0 when the cost cannot reach it).
                unionCost_ = maxCost;
                cumulativeMeasures_.clear();
                double total = 0.0;
                for (const double cost : pairCosts_)
                    cumulativeMeasures_.push_back(total += informedMeasure(dim_, maxCost, cost, spaceMeasure_));
            }
            // Their sum bounds the union's measure: below the space's, drawing from them wastes less than
            // drawing from the bounds (several goals drew from the bounds only, and in R^8 most batches ended
            // far short of B after 10 x 10000 rejections).
            useUnion = cumulativeMeasures_.back() > 0.0 && cumulativeMeasures_.back() < spaceMeasure_;
        }
        for (unsigned int attempt = 0; attempt < maxAttempts; ++attempt)
        {
            if (useEllipsoid)
            {
                sampleEllipsoid(0u, maxCost, x);
                if (si_->satisfiesBounds(state))
                    return true;
            }
            else if (useUnion)
            {
                if (sampleUnion(maxCost, x) && si_->satisfiesBounds(state))
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
