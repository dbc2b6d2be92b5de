#include "lit/litstar/RandomGeometricGraph.h"

#include "lit/InformedMeasure.h"

#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/util/Exception.h>

#include <algorithm>
#include <cmath>

namespace lit::litstar
{
    namespace
    {
        std::vector<double> coordinates(const ompl::base::State *state, unsigned int dim)
        {
            const double *v = state->as<ompl::base::RealVectorStateSpace::StateType>()->values;
            return {v, v + dim};
        }
    }  // namespace

    RandomGeometricGraph::RandomGeometricGraph(const ompl::base::SpaceInformationPtr &si, std::uint_fast32_t seed)
      : si_(si), sampler_(si, seed)
    {
        validNN_.setDistanceFunction([this](State *const &a, State *const &b) { return si_->distance(a->raw_, b->raw_); });
        invalidNN_.setDistanceFunction(
            [this](ompl::base::State *const &a, ompl::base::State *const &b) { return si_->distance(a, b); });
    }

    RandomGeometricGraph::~RandomGeometricGraph()
    {
        clear();
    }

    void RandomGeometricGraph::clear()
    {
        validNN_.clear();
        invalidNN_.clear();
        for (auto &state : states_)
            si_->freeState(state->raw_);
        states_.clear();
        for (auto *raw : invalid_)
            si_->freeState(raw);
        invalid_.clear();
        start_ = nullptr;
        goals_.clear();
        invalidDraws_ = validDraws_ = 0u;
        ++version_;
    }

    State *RandomGeometricGraph::createState(ompl::base::State *raw)
    {
        states_.push_back(std::make_unique<State>(nextId_++, raw));
        return states_.back().get();
    }

    void RandomGeometricGraph::computeLowerBounds(State *state) const
    {
        state->costToComeLowerBound_ = si_->distance(start_->raw_, state->raw_);
        double toGoal = std::numeric_limits<double>::infinity();
        for (const State *goal : goals_)
            toGoal = std::min(toGoal, si_->distance(state->raw_, goal->raw_));
        state->costToGoLowerBound_ = toGoal;
    }

    void RandomGeometricGraph::setTerminals(const ompl::base::State *start,
                                            const std::vector<const ompl::base::State *> &goals)
    {
        const unsigned int dim = si_->getStateDimension();
        start_ = createState(si_->cloneState(start));
        start_->isStart_ = true;
        std::vector<std::vector<double>> goalCoordinates;
        for (const auto *goal : goals)
        {
            State *state = createState(si_->cloneState(goal));
            state->isGoal_ = true;
            goals_.push_back(state);
            goalCoordinates.push_back(coordinates(goal, dim));
        }
        sampler_.setFoci(coordinates(start, dim), goalCoordinates);
        for (auto &state : states_)
        {
            computeLowerBounds(state.get());
            validNN_.add(state.get());
        }
        ++version_;
    }

    std::size_t RandomGeometricGraph::addBatch(std::size_t batchSize, double maxCost)
    {
        std::vector<State *> added;
        std::vector<ompl::base::State *> rejected;
        added.reserve(batchSize);
        std::size_t failures = 0u;
        while (added.size() < batchSize && failures < 10u)
        {
            ompl::base::State *raw = si_->allocState();
            if (!sampler_.sample(maxCost, raw))
            {
                si_->freeState(raw);
                ++failures;  // the informed set is (numerically) empty inside the bounds
                continue;
            }
            if (si_->isValid(raw))
            {
                State *state = createState(raw);
                computeLowerBounds(state);
                added.push_back(state);
                ++validDraws_;
            }
            else
            {
                rejected.push_back(raw);
                ++invalidDraws_;
            }
        }
        if (!added.empty())
            validNN_.add(added);
        if (!rejected.empty())
        {
            invalid_.insert(invalid_.end(), rejected.begin(), rejected.end());
            invalidNN_.add(rejected);
        }
        ++version_;
        return added.size();
    }

    State *RandomGeometricGraph::addValidSample(const std::vector<double> &x)
    {
        ompl::base::State *raw = si_->allocState();
        si_->getStateSpace()->copyFromReals(raw, x);
        State *state = createState(raw);
        if (start_ != nullptr)
            computeLowerBounds(state);
        validNN_.add(state);
        ++version_;
        return state;
    }

    void RandomGeometricGraph::addInvalidSample(const std::vector<double> &x)
    {
        ompl::base::State *raw = si_->allocState();
        si_->getStateSpace()->copyFromReals(raw, x);
        invalid_.push_back(raw);
        invalidNN_.add(raw);
        ++version_;
    }

    std::size_t RandomGeometricGraph::prune(double maxCost, const std::function<void(State *)> &beforeRemove)
    {
        if (!std::isfinite(maxCost))
            return 0u;
        std::size_t removed = 0u;
        std::vector<std::unique_ptr<State>> kept;
        kept.reserve(states_.size());
        for (auto &state : states_)
        {
            const bool terminal = state->isStart_ || state->isGoal_;
            if (!terminal && state->costToComeLowerBound_ + state->costToGoLowerBound_ > maxCost)
            {
                beforeRemove(state.get());
                si_->freeState(state->raw_);
                ++removed;
            }
            else
                kept.push_back(std::move(state));
        }
        std::vector<ompl::base::State *> keptInvalid;
        keptInvalid.reserve(invalid_.size());
        for (auto *raw : invalid_)
        {
            if (sampler_.heuristicCost(raw->as<ompl::base::RealVectorStateSpace::StateType>()->values) > maxCost)
            {
                si_->freeState(raw);
                ++removed;
            }
            else
                keptInvalid.push_back(raw);
        }
        states_ = std::move(kept);
        invalid_ = std::move(keptInvalid);
        if (removed > 0u)
        {
            validNN_.clear();
            std::vector<State *> all;
            all.reserve(states_.size());
            for (auto &state : states_)
                all.push_back(state.get());
            validNN_.add(all);
            invalidNN_.clear();
            invalidNN_.add(invalid_);
            ++version_;
        }
        return removed;
    }

    const std::vector<State *> &RandomGeometricGraph::neighbours(State *state, std::size_t k)
    {
        if (state->neighboursVersion_ == version_ && state->neighboursK_ == k)
            return state->neighbours_;
        state->neighbours_.clear();
        validNN_.nearestK(state, k + 1u, state->neighbours_);
        state->neighbours_.erase(std::remove(state->neighbours_.begin(), state->neighbours_.end(), state),
                                 state->neighbours_.end());
        if (state->neighbours_.size() > k)
            state->neighbours_.resize(k);
        state->neighboursVersion_ = version_;
        state->neighboursK_ = k;
        return state->neighbours_;
    }

    double RandomGeometricGraph::ratioCalc() const
    {
        const double total = static_cast<double>(states_.size() + invalid_.size());
        return total > 0.0 ? static_cast<double>(invalid_.size()) / total : 0.0;
    }

    double RandomGeometricGraph::localRatio(const ompl::base::State *centre, double radius) const
    {
        query_.raw_ = const_cast<ompl::base::State *>(centre);
        std::vector<State *> valid;
        std::vector<ompl::base::State *> invalid;
        if (validNN_.size() > 0u)
            validNN_.nearestR(&query_, radius, valid);
        if (invalidNN_.size() > 0u)
            invalidNN_.nearestR(const_cast<ompl::base::State *>(centre), radius, invalid);
        query_.raw_ = nullptr;
        const double total = static_cast<double>(valid.size() + invalid.size());
        return total > 0.0 ? static_cast<double>(invalid.size()) / total : -1.0;
    }

    std::pair<double, double> RandomGeometricGraph::localRatioCalc(
        const std::vector<const ompl::base::State *> &pathStates, const ompl::base::State *centre, double radius) const
    {
        const double global = ratioCalc();
        double localB = global;
        if (!pathStates.empty())
        {
            double sum = 0.0;
            for (const auto *state : pathStates)
            {
                const double ratio = localRatio(state, radius);
                sum += ratio >= 0.0 ? ratio : global;
            }
            localB = sum / static_cast<double>(pathStates.size());
        }
        double localK = global;
        if (centre != nullptr)
        {
            const double ratio = localRatio(centre, radius);
            if (ratio >= 0.0)
                localK = ratio;
        }
        return {localB, localK};
    }

    double RandomGeometricGraph::radius(double rewireFactor, double informed) const
    {
        const double n = static_cast<double>(si_->getStateDimension());
        const double q = std::max(static_cast<double>(states_.size()), 2.0);
        return rewireFactor * std::pow(2.0 * (1.0 + 1.0 / n) * (informed / unitBallMeasure(si_->getStateDimension())) *
                                           (std::log(q) / q),
                                       1.0 / n);
    }
}  // namespace lit::litstar
