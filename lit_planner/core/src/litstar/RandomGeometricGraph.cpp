#include "lit/litstar/RandomGeometricGraph.h"

#include "lit/InformedMeasure.h"

#include <ompl/base/spaces/RealVectorStateSpace.h>

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

        /** \brief Strict order of neighbour candidates: distance, then id (deterministic ties). */
        bool closer(double da, const State *a, double db, const State *b)
        {
            return da != db ? da < db : a->id_ < b->id_;
        }
    }  // namespace

    RandomGeometricGraph::RandomGeometricGraph(const ompl::base::SpaceInformationPtr &si, std::uint_fast32_t seed)
      : si_(si), sampler_(si, seed), dim_(si->getStateDimension())
    {
    }

    RandomGeometricGraph::~RandomGeometricGraph()
    {
        clear();
    }

    const double *RandomGeometricGraph::coordinatesOf(const ompl::base::State *raw)
    {
        return raw->as<ompl::base::RealVectorStateSpace::StateType>()->values;
    }

    void RandomGeometricGraph::clear()
    {
        for (auto &state : states_)
            si_->freeState(state->raw_);
        states_.clear();
        for (auto *raw : invalid_)
            si_->freeState(raw);
        invalid_.clear();
        start_ = nullptr;
        goals_.clear();
        invalidDraws_ = validDraws_ = 0u;
        ++pruneEpoch_;
        ++version_;
    }

    State *RandomGeometricGraph::createState(ompl::base::State *raw)
    {
        states_.push_back(std::make_unique<State>(nextId_++, raw, coordinatesOf(raw)));
        return states_.back().get();
    }

    void RandomGeometricGraph::computeLowerBounds(State *state) const
    {
        state->costToComeLowerBound_ = distance(start_, state);
        double toGoal = std::numeric_limits<double>::infinity();
        for (const State *goal : goals_)
            toGoal = std::min(toGoal, distance(state, goal));
        state->costToGoLowerBound_ = toGoal;
    }

    void RandomGeometricGraph::setTerminals(const ompl::base::State *start,
                                            const std::vector<const ompl::base::State *> &goals)
    {
        start_ = createState(si_->cloneState(start));
        start_->isStart_ = true;
        std::vector<std::vector<double>> goalCoordinates;
        for (const auto *goal : goals)
        {
            State *state = createState(si_->cloneState(goal));
            state->isGoal_ = true;
            goals_.push_back(state);
            goalCoordinates.push_back(coordinates(goal, dim_));
        }
        sampler_.setFoci(coordinates(start, dim_), goalCoordinates);
        for (auto &state : states_)
            computeLowerBounds(state.get());
        ++version_;
    }

    std::size_t RandomGeometricGraph::addBatch(std::size_t batchSize, double maxCost)
    {
        std::size_t added = 0u;
        std::size_t failures = 0u;
        while (added < batchSize && failures < 10u)
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
                computeLowerBounds(createState(raw));
                ++added;
                ++validDraws_;
            }
            else
            {
                invalid_.push_back(raw);
                ++invalidDraws_;
            }
        }
        ++version_;
        return added;
    }

    State *RandomGeometricGraph::addValidSample(const std::vector<double> &x)
    {
        ompl::base::State *raw = si_->allocState();
        si_->getStateSpace()->copyFromReals(raw, x);
        State *state = createState(raw);
        if (start_ != nullptr)
            computeLowerBounds(state);
        ++version_;
        return state;
    }

    void RandomGeometricGraph::addInvalidSample(const std::vector<double> &x)
    {
        ompl::base::State *raw = si_->allocState();
        si_->getStateSpace()->copyFromReals(raw, x);
        invalid_.push_back(raw);
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
        states_ = std::move(kept);
        std::vector<ompl::base::State *> keptInvalid;
        keptInvalid.reserve(invalid_.size());
        for (auto *raw : invalid_)
        {
            if (sampler_.heuristicCost(coordinatesOf(raw)) > maxCost)
            {
                si_->freeState(raw);
                ++removed;
            }
            else
                keptInvalid.push_back(raw);
        }
        invalid_ = std::move(keptInvalid);
        if (removed > 0u)
        {
            // Incoming lists may hold removed states; they are rebuilt as the neighbour lists are recomputed.
            for (auto &state : states_)
                state->incomingNeighbours_.clear();
            ++pruneEpoch_;  // cached neighbour lists may hold removed states and their positions shifted
            ++version_;
        }
        return removed;
    }

    void RandomGeometricGraph::scanNeighbours(State *state, std::size_t k, std::size_t from)
    {
        // Merge the cached list with the candidates states_[from, end): a bounded max-heap on (distance, id).
        std::vector<std::pair<double, State *>> best;
        best.reserve(k + 1u);
        auto worse = [](const std::pair<double, State *> &a, const std::pair<double, State *> &b) {
            return closer(a.first, a.second, b.first, b.second);
        };
        for (std::size_t i = 0; i < state->neighbours_.size(); ++i)
            best.emplace_back(state->neighbourDistances_[i], state->neighbours_[i]);
        std::make_heap(best.begin(), best.end(), worse);
        for (std::size_t i = from; i < states_.size(); ++i)
        {
            State *other = states_[i].get();
            if (other == state)
                continue;
            const double d = distance(state, other);
            if (best.size() < k)
            {
                best.emplace_back(d, other);
                std::push_heap(best.begin(), best.end(), worse);
            }
            else if (k > 0u && closer(d, other, best.front().first, best.front().second))
            {
                std::pop_heap(best.begin(), best.end(), worse);
                best.back() = {d, other};
                std::push_heap(best.begin(), best.end(), worse);
            }
        }
        std::sort_heap(best.begin(), best.end(), worse);
        state->neighbours_.clear();
        state->neighbourDistances_.clear();
        for (const auto &[d, other] : best)
        {
            state->neighbours_.push_back(other);
            state->neighbourDistances_.push_back(d);
        }
        state->neighboursScanned_ = states_.size();
        for (State *other : state->neighbours_)
        {
            auto &incoming = other->incomingNeighbours_;
            if (std::find(incoming.begin(), incoming.end(), state) == incoming.end())
                incoming.push_back(state);
        }
    }

    const std::vector<State *> &RandomGeometricGraph::incomingNeighbours(State *state)
    {
        auto &incoming = state->incomingNeighbours_;
        incoming.erase(std::remove_if(incoming.begin(), incoming.end(),
                                      [state](const State *other) {
                                          return std::find(other->neighbours_.begin(), other->neighbours_.end(),
                                                           state) == other->neighbours_.end();
                                      }),
                       incoming.end());
        return incoming;
    }

    const std::vector<State *> &RandomGeometricGraph::neighbours(State *state, std::size_t k)
    {
        if (state->neighboursEpoch_ == pruneEpoch_ && state->neighboursK_ == k)
        {
            if (state->neighboursScanned_ < states_.size())
                scanNeighbours(state, k, state->neighboursScanned_);
            return state->neighbours_;
        }
        state->neighbours_.clear();
        state->neighbourDistances_.clear();
        scanNeighbours(state, k, 0u);
        state->neighboursEpoch_ = pruneEpoch_;
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
        const double *c = coordinatesOf(centre);
        std::size_t valid = 0u, invalid = 0u;
        for (const auto &state : states_)
            valid += distance(c, state->coordinates_) <= radius ? 1u : 0u;
        for (const auto *raw : invalid_)
            invalid += distance(c, coordinatesOf(raw)) <= radius ? 1u : 0u;
        const double total = static_cast<double>(valid + invalid);
        return total > 0.0 ? static_cast<double>(invalid) / total : -1.0;
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
        const double n = static_cast<double>(dim_);
        const double q = std::max(static_cast<double>(states_.size()), 2.0);
        return rewireFactor * std::pow(2.0 * (1.0 + 1.0 / n) * (informed / unitBallMeasure(dim_)) * (std::log(q) / q),
                                       1.0 / n);
    }
}  // namespace lit::litstar
