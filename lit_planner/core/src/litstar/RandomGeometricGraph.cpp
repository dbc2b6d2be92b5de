#include "lit/litstar/RandomGeometricGraph.h"

#include "lit/InformedMeasure.h"

#include <ompl/base/spaces/RealVectorStateSpace.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

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
      : si_(si)
      , sampler_(si, seed)
      , floatFilter_(si->getStateDimension() > 8u)
      , floatStride_((si->getStateDimension() + 3u) / 4u * 4u)
      , dim_(si->getStateDimension())
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
        packed_.clear();
        packedFloat_.clear();
        maxAbsCoordinate_ = 0.0;
        packedInvalid_.clear();
        starts_.clear();
        goals_.clear();
        invalidDraws_ = validDraws_ = 0u;
        ++cacheEpoch_;
        ++version_;
    }

    State *RandomGeometricGraph::createState(ompl::base::State *raw)
    {
        const double *x = coordinatesOf(raw);
        states_.push_back(std::make_unique<State>(nextId_++, raw, x));
        appendValid(x);
        return states_.back().get();
    }

    void RandomGeometricGraph::appendValid(const double *x)
    {
        appendPacked(packed_, x);
        if (!floatFilter_)
            return;
        for (unsigned int i = 0; i < dim_; ++i)
        {
            packedFloat_.push_back(static_cast<float>(x[i]));
            const double magnitude = std::abs(x[i]);
            // A NaN stays (it turns the filter off until the next clear or prune): a later coordinate must not
            // replace it with a bound that leaves out the samples before it.
            if (!(magnitude <= maxAbsCoordinate_) && !std::isnan(maxAbsCoordinate_))
                maxAbsCoordinate_ = magnitude;
        }
        packedFloat_.insert(packedFloat_.end(), floatStride_ - dim_, 0.0f);
    }

    void RandomGeometricGraph::appendPacked(std::vector<double> &packed, const double *x) const
    {
        packed.insert(packed.end(), x, x + dim_);
    }

    void RandomGeometricGraph::computeLowerBounds(State *state) const
    {
        double fromStart = std::numeric_limits<double>::infinity();
        for (const State *start : starts_)
            fromStart = std::min(fromStart, distance(start, state));
        state->costToComeLowerBound_ = fromStart;
        double toGoal = std::numeric_limits<double>::infinity();
        for (const State *goal : goals_)
            toGoal = std::min(toGoal, distance(state, goal));
        state->costToGoLowerBound_ = toGoal;
    }

    void RandomGeometricGraph::setTerminals(const std::vector<const ompl::base::State *> &starts,
                                            const std::vector<const ompl::base::State *> &goals)
    {
        // The starts first (ids 0, 1, ...), then the goals: the order the searches' ties break by.
        const auto add = [this](const std::vector<const ompl::base::State *> &raws, bool isStart,
                                std::vector<State *> &into) {
            std::vector<std::vector<double>> foci;
            for (const auto *raw : raws)
            {
                State *state = createState(si_->cloneState(raw));
                (isStart ? state->isStart_ : state->isGoal_) = true;
                into.push_back(state);
                foci.push_back(coordinates(raw, dim_));
            }
            return foci;
        };
        const std::vector<std::vector<double>> startCoordinates = add(starts, true, starts_);
        const std::vector<std::vector<double>> goalCoordinates = add(goals, false, goals_);
        sampler_.setFoci(startCoordinates, goalCoordinates);
        for (auto &state : states_)
            computeLowerBounds(state.get());
        ++version_;
    }

    void RandomGeometricGraph::addGoals(const std::vector<const ompl::base::State *> &goals)
    {
        if (goals.empty())
            return;
        const std::size_t first = goals_.size();
        for (const auto *raw : goals)
        {
            State *state = createState(si_->cloneState(raw));
            state->isGoal_ = true;
            goals_.push_back(state);
        }
        std::vector<std::vector<double>> startFoci, goalFoci;
        for (const State *start : starts_)
            startFoci.push_back(coordinates(start->raw_, dim_));
        for (const State *goal : goals_)
            goalFoci.push_back(coordinates(goal->raw_, dim_));
        sampler_.setFoci(startFoci, goalFoci);
        for (auto &state : states_)  // a new goal can only bring a sample's bound down
        {
            if (state->isGoal_ && state->id_ >= goals_[first]->id_)
                computeLowerBounds(state.get());
            else
                for (std::size_t g = first; g < goals_.size(); ++g)
                    state->costToGoLowerBound_ =
                        std::min(state->costToGoLowerBound_, distance(state.get(), goals_[g]));
        }
        ++version_;
    }

    std::size_t RandomGeometricGraph::addBatch(std::size_t batchSize, double maxCost,
                                               const std::function<bool()> &stop)
    {
        std::size_t added = 0u;
        std::size_t failures = 0u;
        std::size_t draws = 0u;
        // Reused until a valid sample takes it; freed however the loop ends (a user's validity checker may throw).
        const auto freeState = [this](ompl::base::State *state) { si_->freeState(state); };
        std::unique_ptr<ompl::base::State, decltype(freeState)> raw(nullptr, freeState);
        const std::size_t maxDraws =
            batchSize > std::numeric_limits<std::size_t>::max() / MAX_DRAWS_PER_SAMPLE ?
                std::numeric_limits<std::size_t>::max() :
                MAX_DRAWS_PER_SAMPLE * batchSize;
        bool stopped = false;
        while (added < batchSize && failures < 10u && draws < maxDraws)
        {
            if (++draws % STOP_CHECK_INTERVAL == 0u && stop && stop())
            {
                stopped = true;
                break;
            }
            if (!raw)
                raw.reset(si_->allocState());
            if (!sampler_.sample(maxCost, raw.get()))
            {
                ++failures;  // the informed set is (numerically) empty inside the bounds
                continue;
            }
            if (si_->isValid(raw.get()))
            {
                computeLowerBounds(createState(raw.release()));
                ++added;
                ++validDraws_;
            }
            else
            {
                appendPacked(packedInvalid_, coordinatesOf(raw.get()));
                ++invalidDraws_;
            }
        }
        lastBatchCapped_ = added < batchSize && failures < 10u && !stopped && draws >= maxDraws;
        ++version_;
        return added;
    }

    State *RandomGeometricGraph::addValidSample(const std::vector<double> &x)
    {
        ompl::base::State *raw = si_->allocState();
        si_->getStateSpace()->copyFromReals(raw, x);
        State *state = createState(raw);
        if (!starts_.empty())
            computeLowerBounds(state);
        ++version_;
        return state;
    }

    void RandomGeometricGraph::addInvalidSample(const std::vector<double> &x)
    {
        if (x.size() != dim_)
            throw std::invalid_argument("RandomGeometricGraph: an invalid sample of the wrong dimension");
        appendPacked(packedInvalid_, x.data());
        ++version_;
    }

    std::size_t RandomGeometricGraph::prune(double maxCost, const std::function<void(State *)> &beforeRemove)
    {
        if (!std::isfinite(maxCost))
            return 0u;
        std::size_t removed = 0u;
        // keptBefore[i]: kept samples among states_[0, i), the new position of old position i.
        std::vector<std::size_t> keptBefore(states_.size() + 1u, 0u);
        for (std::size_t i = 0; i < states_.size(); ++i)
        {
            State *state = states_[i].get();
            const bool kept = state->isStart_ || state->isGoal_ || state->pinned_;
            state->pruned_ = !kept && state->costToComeLowerBound_ + state->costToGoLowerBound_ > maxCost;
            keptBefore[i + 1u] = keptBefore[i] + (state->pruned_ ? 0u : 1u);
        }
        std::vector<std::unique_ptr<State>> kept;
        kept.reserve(keptBefore.back());
        for (auto &state : states_)
        {
            if (!state->pruned_)
            {
                kept.push_back(std::move(state));
                continue;
            }
            beforeRemove(state.get());
            si_->freeState(state->raw_);
            state->raw_ = nullptr;
            ++removed;
        }
        if (removed > 0u)
        {
            // The neighbour caches stay exact without the removed samples: a cache held the cap nearest of what its
            // sample had scanned, so what is left of it is the nearest of what is left, in the same order. A full
            // cache that lost entries is full at its new size (samples beyond its old last entry are unknown).
            for (auto &state : kept)
            {
                if (state->neighboursEpoch_ != cacheEpoch_)
                    continue;
                auto &list = state->neighbours_;
                auto &distances = state->neighbourDistances_;
                const bool full = list.size() >= state->neighboursCap_;
                std::size_t out = 0u;
                for (std::size_t i = 0; i < list.size(); ++i)
                {
                    if (list[i]->pruned_)
                        continue;
                    list[out] = list[i];
                    distances[out] = distances[i];
                    ++out;
                }
                if (out < list.size())
                {
                    list.resize(out);
                    distances.resize(out);
                    if (full)
                        state->neighboursCap_ = out;
                }
                state->neighboursScanned_ = keptBefore[state->neighboursScanned_];
            }
        }
        states_ = std::move(kept);  // destroys the removed samples
        packed_.clear();
        packedFloat_.clear();
        maxAbsCoordinate_ = 0.0;
        for (const auto &state : states_)
            appendValid(state->coordinates_);
        std::size_t out = 0u;  // compacted in place, in order
        for (std::size_t at = 0u; at < packedInvalid_.size(); at += dim_)
        {
            if (sampler_.heuristicCost(packedInvalid_.data() + at) > maxCost)
            {
                ++removed;
                continue;
            }
            if (out != at)
                std::copy_n(packedInvalid_.begin() + static_cast<std::ptrdiff_t>(at), dim_,
                            packedInvalid_.begin() + static_cast<std::ptrdiff_t>(out));
            out += dim_;
        }
        packedInvalid_.resize(out);
        if (removed > 0u)
        {
            // Incoming lists may hold removed states: they are rebuilt as the samples are asked for their
            // neighbours again (in the order a fresh start would rebuild them).
            for (auto &state : states_)
            {
                state->incomingNeighbours_.clear();
                state->incomingDistances_.clear();
            }
            ++incomingEpoch_;
            ++version_;
        }
        return removed;
    }

    void RandomGeometricGraph::scanNeighbours(State *state, std::size_t cap, std::size_t from)
    {
        state->neighboursScanned_ = states_.size();
        if (cap == 0u)
            return;
        // The candidates states_[from, end) that beat the cache's last entry (all while it is not full), sorted,
        // then merged into the sorted cache and cut back to the cap. Most incremental scans find few or none.
        auto &list = state->neighbours_;
        auto &distances = state->neighbourDistances_;
        const bool full = list.size() >= cap;
        const double worstDistance = full ? distances.back() : std::numeric_limits<double>::infinity();
        const State *worstState = full ? list.back() : nullptr;
        // Squared distances over the packed coordinates (a linear sweep); a sum above the cache's last squared
        // distance (with a margin far above rounding, so no tie is lost) is dropped without its sqrt, and the sqrt
        // of a kept sum is bit-identical to distance(). (Leaving the sum early, dimension by dimension, measured
        // slower in R^16: the branch costs more than the few dimensions it saves.)
        const double bound = worstDistance * worstDistance * (1.0 + 1e-9);
        // A scan into an empty cache (a rescan) with more samples than the cap: the bound tightens as the scan goes,
        // to the cap-th smallest sum among the candidates so far (with the same margin). A sample among the cap
        // nearest of the whole scan has a sum within the margin of the scan's cap-th smallest, which is at most the
        // running one, so it passes and is kept; without the bound every sample took a sqrt and the selection
        // below (a rescan in R^16 was most of LIT*'s time).
        const bool tighten = list.empty() && states_.size() - from > cap;
        const double *x = state->coordinates_;
        const bool terminal = state->isGoal_ || state->isStart_;
        auto &candidates = candidates_;
        candidates.clear();
        const auto scan = [&](auto tightenTag)
        {
            constexpr bool Tighten = decltype(tightenTag)::value;
            double limit = bound;
            const double *y = packed_.data() + from * dim_;
            // A sample whose sum passed the bound (a sum above it is farther than the cache's last entry, or than
            // the running bound).
            const auto handle = [&](std::size_t i, double sum)
            {
                State *other = states_[i].get();
                // A goal's neighbours are the samples that are not goals: no search uses an edge between two goals
                // (the reverse search starts at every goal with cost 0, the forward search never leaves one), and a
                // goal among many close ones had only goals as its k nearest, so the reverse search never left the
                // goal set (100 goal-region samples in a box of side 0.02 left every search idle).
                // The start's neighbours are not goals either: the start-goal lines are checked first of all
                // (connectTerminals), so such an edge is a solution already or known blocked. In R^16 a goal region
                // 0.4 from the start had all of the start's k nearest in it (uniform samples were 1.2 away), every
                // one of them behind the wall: the forward search never had an edge, and batches followed each other
                // with no search step. Nor are other starts (with several): the forward search never enters a start,
                // and the reverse search ends at one.
                // The flags of state first: other's are read (a cache miss per sample) only for a terminal.
                if (other == state || (terminal && other->isGoal_) || (state->isStart_ && other->isStart_))
                    return;
                if constexpr (Tighten)
                {
                    // The sum for now (its sqrt once the scan is done). Now and then the candidates are cut back to
                    // the cap smallest sums and those within the margin of the cap-th, whose margin is the new bound.
                    candidates.emplace_back(sum, other);
                    if (candidates.size() >= 2u * cap + 64u)
                    {
                        const auto nth = candidates.begin() + static_cast<std::ptrdiff_t>(cap - 1u);
                        std::nth_element(candidates.begin(), nth, candidates.end(),
                                         [](const auto &a, const auto &b) { return a.first < b.first; });
                        limit = nth->first * (1.0 + 1e-9);
                        candidates.erase(std::partition(nth + 1, candidates.end(),
                                                        [limit](const auto &c) { return c.first <= limit; }),
                                         candidates.end());
                    }
                }
                else
                {
                    const double d = std::sqrt(sum);
                    if (!full || closer(d, other, worstDistance, worstState))
                        candidates.emplace_back(d, other);
                }
            };
            // Four samples at a time. With a finite bound, the single-precision sums drop the samples that are
            // certainly beyond it, and only the others take the double sum. The error bound: with u = 2^-24, M the
            // largest |coordinate| and n = floatStride_ terms, each float difference is within 4.02 u M of the
            // exact one, so each float square is at most the exact one plus 16.1 u M^2 (before its own rounding),
            // and the float sum of n non-negative terms is at most (1 + u)^n <= 1 + 2 n u times the sum of its terms
            // (plus 1e-38 for subnormal rounding). A float sum above ((limit (1 + 1e-9) + 20 n u M^2 + 1e-38)
            // (1 + 2 n u)) (1 + 1e-6) is therefore of an exact sum above limit (1 + 1e-9), whose double sum (within
            // (n + 1) 2^-53 of it) is above limit. Such a sample is dropped by the exact test as well: the samples
            // that reach handle() are the same. Otherwise four independent double sums (each added in the order of
            // squaredDistance(), so bit-identical to it) keep the adder busy where one waits on its last addition.
            const double u = std::ldexp(1.0, -24);
            const double n = static_cast<double>(floatStride_);
            const bool useFloat = floatFilter_ && maxAbsCoordinate_ < 1e15;  // false for an inf or NaN coordinate too
            const double slack = 20.0 * n * u * maxAbsCoordinate_ * maxAbsCoordinate_ + 1e-38;
            const double growth = (1.0 + 2.0 * n * u) * (1.0 + 1e-6);
            auto &xf = queryFloat_;
            if (useFloat)
            {
                xf.assign(floatStride_, 0.0f);
                for (unsigned int d = 0; d < dim_; ++d)
                    xf[d] = static_cast<float>(x[d]);
            }
            std::size_t i = from;
            const std::size_t end = states_.size();
            for (; i + 4u <= end; i += 4u, y += 4u * dim_)
            {
                if (useFloat && limit < std::numeric_limits<double>::infinity())
                {
                    const double floatLimit = (limit * (1.0 + 1e-9) + slack) * growth;
                    float approximate[4];
                    floatSquaredDistances4(xf.data(), packedFloat_.data() + i * floatStride_, approximate);
                    for (std::size_t j = 0; j < 4u; ++j)
                    {
                        if (static_cast<double>(approximate[j]) > floatLimit)
                            continue;  // the double sum is above limit too
                        const double sum = squaredDistance(x, y + j * dim_);
                        if (!(sum > limit))
                            handle(i + j, sum);
                    }
                    continue;
                }
                double sums[4];
                squaredDistances4(x, y, sums);
                for (std::size_t j = 0; j < 4u; ++j)
                    if (!(sums[j] > limit))
                        handle(i + j, sums[j]);
            }
            for (; i < end; ++i, y += dim_)
            {
                const double sum = squaredDistance(x, y);
                if (!(sum > limit))
                    handle(i, sum);
            }
            if constexpr (Tighten)
                for (auto &candidate : candidates)
                    candidate.first = std::sqrt(candidate.first);
        };
        if (tighten)
            scan(std::true_type{});
        else
            scan(std::false_type{});
        if (candidates.empty())
            return;
        auto order = [](const std::pair<double, State *> &a, const std::pair<double, State *> &b) {
            return closer(a.first, a.second, b.first, b.second);
        };
        if (candidates.size() > cap)
        {
            std::nth_element(candidates.begin(), candidates.begin() + static_cast<std::ptrdiff_t>(cap),
                             candidates.end(), order);
            candidates.resize(cap);
        }
        std::sort(candidates.begin(), candidates.end(), order);
        merged_.clear();
        std::size_t i = 0u, j = 0u;
        while (merged_.size() < cap && (i < list.size() || j < candidates.size()))
        {
            if (j == candidates.size() ||
                (i < list.size() && closer(distances[i], list[i], candidates[j].first, candidates[j].second)))
            {
                merged_.emplace_back(distances[i], list[i]);
                ++i;
            }
            else
                merged_.push_back(candidates[j++]);
        }
        list.clear();
        distances.clear();
        for (const auto &[d, other] : merged_)
        {
            list.push_back(other);
            distances.push_back(d);
        }
    }

    bool RandomGeometricGraph::inAskedPrefix(const State *owner, const State *state, double distance) const
    {
        // state was in owner's prefix at some point since the last prune, so owner has scanned it, and owner's
        // cache is exact over what it scanned: state is in the prefix iff it is not farther than the prefix's
        // last entry (distance, then id), or the prefix is the whole of a cache that is not full.
        const auto &list = owner->neighbours_;
        const std::size_t size = std::min(owner->neighboursK_, list.size());
        if (size == 0u)
            return false;
        if (size == list.size() && list.size() < owner->neighboursCap_)
            return true;
        if (list[size - 1u] == state)
            return true;  // the boundary itself: decided without recomputing its distance
        return !closer(owner->neighbourDistances_[size - 1u], list[size - 1u], distance, state);
    }

    const std::vector<State *> &RandomGeometricGraph::incomingNeighbours(State *state)
    {
        // In place and in order (as std::remove_if), the distances alongside.
        auto &incoming = state->incomingNeighbours_;
        auto &distances = state->incomingDistances_;
        std::size_t kept = 0u;
        for (std::size_t i = 0; i < incoming.size(); ++i)
        {
            if (!inAskedPrefix(incoming[i], state, distances[i]))
                continue;
            incoming[kept] = incoming[i];
            distances[kept] = distances[i];
            ++kept;
        }
        incoming.resize(kept);
        distances.resize(kept);
        return incoming;
    }

    NeighbourRange RandomGeometricGraph::neighbours(State *state, std::size_t k)
    {
        const bool cacheValid = state->neighboursEpoch_ == cacheEpoch_;
        // The prefix asked for last time since the last prune is in its members' incoming lists already: remember
        // its last entry and where the samples this call scans for the first time begin (ids grow along states_).
        const bool sameEpoch = cacheValid && state->incomingEpoch_ == incomingEpoch_;
        const std::size_t lastSize = sameEpoch ? std::min(state->neighboursK_, state->neighbours_.size()) : 0u;
        // A prefix that was the whole of a cache that was not full held every sample scanned until then.
        const bool wholeCache =
            lastSize == state->neighbours_.size() && state->neighbours_.size() < state->neighboursCap_;
        const double lastDistance = lastSize > 0u ? state->neighbourDistances_[lastSize - 1u] : 0.0;
        const State *lastEntry = lastSize > 0u ? state->neighbours_[lastSize - 1u] : nullptr;
        const std::size_t firstNewId = !sameEpoch ? 0u
                                       : state->neighboursScanned_ < states_.size()
                                           ? states_[state->neighboursScanned_]->id_
                                           : std::numeric_limits<std::size_t>::max();
        if (!cacheValid || k > state->neighboursCap_)
        {
            // A rescan (first use, or k above the cap): grow the cap geometrically, so a k that keeps rising
            // (psi_K decided per expansion, or log q growing with the batches) rescans a few times rather than at
            // every rise.
            const std::size_t cap = state->neighboursCap_;
            state->neighboursCap_ = !cacheValid && k <= cap ? cap : std::max(k, cap + cap / 2u);
            state->neighbours_.clear();
            state->neighbourDistances_.clear();
            scanNeighbours(state, state->neighboursCap_, 0u);
            state->neighboursEpoch_ = cacheEpoch_;
        }
        else if (state->neighboursScanned_ < states_.size())
            scanNeighbours(state, state->neighboursCap_, state->neighboursScanned_);
        const std::size_t size = std::min(k, state->neighbours_.size());
        for (std::size_t i = 0; i < size; ++i)
        {
            State *other = state->neighbours_[i];
            const bool wasInPrefix =
                lastSize > 0u && other->id_ < firstNewId &&
                (wholeCache || !closer(lastDistance, lastEntry, state->neighbourDistances_[i], other));
            if (wasInPrefix)
                continue;
            // Stale entries (from a larger k asked earlier) are dropped when the incoming list is read.
            auto &incoming = other->incomingNeighbours_;
            if (std::find(incoming.begin(), incoming.end(), state) == incoming.end())
            {
                incoming.push_back(state);
                other->incomingDistances_.push_back(state->neighbourDistances_[i]);
            }
        }
        state->neighboursK_ = k;
        state->incomingEpoch_ = incomingEpoch_;
        return {state->neighbours_.data(), state->neighbourDistances_.data(), size};
    }

    double RandomGeometricGraph::ratioCalc() const
    {
        const double invalid = static_cast<double>(numInvalid());
        const double total = static_cast<double>(states_.size()) + invalid;
        return total > 0.0 ? invalid / total : 0.0;
    }

    std::size_t RandomGeometricGraph::countWithin(const std::vector<double> &packed, const double *centre,
                                                  double radius) const
    {
        // Squared distances against radius^2; only sums within rounding of it take the sqrt, so the count is
        // exactly that of distance() <= radius.
        if (!(radius >= 0.0))
            return 0u;  // as distance() <= radius: nothing within a negative or NaN radius
        const double squared = radius * radius;
        const double inside = squared * (1.0 - 1e-9);
        const double outside = squared * (1.0 + 1e-9);
        std::size_t count = 0u;
        // sum == 0 is the centre's own position: a state is not its own neighbour (LIT*'s rho_local counts
        // the samples around a state, and an isolated state falls back to rho_global).
        const auto within = [&](double sum) {
            return sum > 0.0 && (sum < inside || (sum <= outside && std::sqrt(sum) <= radius)) ? 1u : 0u;
        };
        const double *y = packed.data();
        const std::size_t points = packed.size() / dim_;
        std::size_t i = 0u;
        for (; i + 4u <= points; i += 4u, y += 4u * dim_)  // four sums side by side, as in scanNeighbours
        {
            double sums[4];
            squaredDistances4(centre, y, sums);
            count += within(sums[0]) + within(sums[1]) + within(sums[2]) + within(sums[3]);
        }
        for (; i < points; ++i, y += dim_)
            count += within(squaredDistance(centre, y));
        return count;
    }

    double RandomGeometricGraph::localRatio(const ompl::base::State *centre, double radius) const
    {
        const double *c = coordinatesOf(centre);
        const std::size_t valid = countWithin(packed_, c, radius);
        const std::size_t invalid = countWithin(packedInvalid_, c, radius);
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
