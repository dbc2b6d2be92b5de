#include "lit/LITstar.h"

#include <functional>

#include "lit/InformedMeasure.h"
#include "NumberText.h"

#include <ompl/base/DiscreteMotionValidator.h>
#include <ompl/base/PlannerData.h>
#include <ompl/base/goals/GoalLazySamples.h>
#include <ompl/base/goals/GoalSampleableRegion.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/geometric/PathGeometric.h>
#include <ompl/util/Exception.h>

#include <algorithm>
#include <cstring>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <typeinfo>

namespace lit
{
    using litstar::State;
    namespace
    {
        constexpr unsigned int fullCheck = std::numeric_limits<unsigned int>::max();
        constexpr double infinity = std::numeric_limits<double>::infinity();

        /** \brief Planner::declareParam, except that a value the setter refuses (ompl::Exception) makes setParam()
         *  answer false with OMPL's warning, as a value that does not parse does (it threw out of setParams()). */
        template <typename T, typename Setter, typename Getter>
        void declareRefusing(ompl::base::ParamSet &params, const std::string &name, LITstar *planner, Setter setter,
                             Getter getter, const std::string &rangeSuggestion = "")
        {
            params.declareParam<T>(
                name,
                [planner, setter](T value)
                {
                    try
                    {
                        (planner->*setter)(value);
                    }
                    catch (const ompl::Exception &error)
                    {
                        planner->noteRefusedParameter(error.what());
                        throw std::invalid_argument(error.what());  // what ParamSet's setValue catches
                    }
                },
                [planner, getter] { return (planner->*getter)(); });
            if (!rangeSuggestion.empty())
                params[name].setRangeSuggestion(rangeSuggestion);
        }

        /** \brief All 17 significant digits (ompl::toString keeps 6: costs differing in the 7th looked equal). */
        std::string exactText(double value)
        {
            std::ostringstream text;
            text.precision(std::numeric_limits<double>::max_digits10);
            text << value;
            return text.str();
        }
    }  // namespace

    LITstar::LITstar(const ompl::base::SpaceInformationPtr &si)
      : ompl::base::Planner(si, "LITstar"), policy_(std::make_shared<FixedPolicy>())
    {
        specs_.recognizedGoal = ompl::base::GOAL_SAMPLEABLE_REGION;
        specs_.multithreaded = false;
        specs_.approximateSolutions = false;
        specs_.optimizingPaths = true;
        specs_.directed = false;  // edges are undirected: a motion is checked in one direction for both
        specs_.provingSolutionNonExistence = false;
        specs_.canReportIntermediateSolutions = true;

        declareRefusing<unsigned int>(params(), "batch_size", this, &LITstar::setBatchSize, &LITstar::getBatchSize,
                                      "1:1:10000");
        declareRefusing<double>(params(), "rewire_factor", this, &LITstar::setRewireFactor,
                                &LITstar::getRewireFactor, "1.0:0.001:3.0");
        declareRefusing<unsigned int>(params(), "decision_interval", this, &LITstar::setDecisionInterval,
                                      &LITstar::getDecisionInterval, "1:1:10000");
        declareRefusing<std::string>(params(), "policy", this, &LITstar::setPolicyName, &LITstar::getPolicyName);
        declareRefusing<unsigned int>(params(), "seed", this, &LITstar::setSeed, &LITstar::getSeed);
        declareRefusing<unsigned int>(params(), "max_iterations", this, &LITstar::setMaxIterations,
                                      &LITstar::getMaxIterations);
        declareRefusing<unsigned int>(params(), "max_batches", this, &LITstar::setMaxBatches, &LITstar::getMaxBatches);
        declareRefusing<double>(params(), "time_budget", this, &LITstar::setTimeBudget, &LITstar::getTimeBudget);

        // What OMPL's Benchmark samples while the planner runs (its cost-over-time curves).
        addPlannerProgressProperty("best cost DOUBLE", [this] { return exactText(bestCost_); });
        addPlannerProgressProperty("iterations INTEGER",
                                   [this] { return std::to_string(counters_.iterations); });
        addPlannerProgressProperty("batches INTEGER", [this] { return std::to_string(counters_.batches); });
        addPlannerProgressProperty("valid samples INTEGER",
                                   [this] { return std::to_string(counters_.validSamples); });
        addPlannerProgressProperty("collision checks INTEGER",
                                   [this] { return std::to_string(counters_.collisionChecks); });
    }

    LITstar::~LITstar()
    {
        if (forwardQueue_)
            forwardQueue_->clear();
        if (interpolated_ != nullptr)
            si_->freeState(interpolated_);
    }

    // ---------------------------------------------------------------------------------------------- parameters
    void LITstar::setBatchSize(unsigned int batchSize)
    {
        if (batchSize == 0u || batchSize > static_cast<unsigned int>(std::numeric_limits<int>::max()))
            throw ompl::Exception("LITstar: the batch size must be between 1 and 2^31 - 1");
        if (policy_ && policy_->name() == "fixed")
            setPolicy(fixedPolicy(batchSize));
        else if (policy_)
            OMPL_WARN("LITstar: batch_size %u is the fixed policy's B; the '%s' policy decides B itself (the value is "
                      "kept for a later setPolicyName(\"fixed\"))",
                      batchSize, policy_->name().c_str());
        fixedBatchSize_ = batchSize;
    }
    ParameterPolicyPtr LITstar::fixedPolicy(unsigned int batchSize) const
    {
        // A fixed policy set before keeps its psi_K (setBatchSize used to reset it to e).
        const double psi = policy_ && policy_->name() == "fixed" ? policy_->initialNeighbourFactor() : M_E;
        return std::make_shared<FixedPolicy>(static_cast<int>(batchSize), psi);
    }
    unsigned int LITstar::getBatchSize() const
    {
        return fixedBatchSize_;
    }
    void LITstar::setRewireFactor(double factor)
    {
        // 0 or less gave K = 1 and inf an overflowed K of 0: planners that never solved, without a word.
        const std::string text = detail::numberText(factor);
        if (!(std::isfinite(factor) && factor > 0.0 && factor <= 1e6))
            throw ompl::Exception("LITstar: the rewire factor must be a number in (0, 1e6], got " + text);
        if (factor < 1.0)
            OMPL_WARN("LITstar: a rewire factor below 1 (%s) gives fewer neighbours than the k-nearest RGG's bound: "
                      "the planner loses asymptotic optimality and, from about 0.05 down, may never connect start and "
                      "goal (K = 1)",
                      text.c_str());
        rewireFactor_ = factor;
    }
    double LITstar::getRewireFactor() const
    {
        return rewireFactor_;
    }
    void LITstar::setDecisionInterval(unsigned int interval)
    {
        decisionInterval_ = std::max(1u, interval);
    }
    unsigned int LITstar::getDecisionInterval() const
    {
        return decisionInterval_;
    }
    void LITstar::setPolicyName(const std::string &name)
    {
        if (name == "fixed")
            setPolicy(fixedPolicy(fixedBatchSize_));
        else if (name == "fit")
            setPolicy(std::make_shared<FitPolicy>());
        else
            throw ompl::Exception("LITstar: policy '" + name +
                                  "' cannot be set by name (use 'fixed' or 'fit'; tensor and external policies "
                                  "are objects: setPolicy())");
    }
    std::string LITstar::getPolicyName() const
    {
        return policy_ ? policy_->name() : "";
    }
    void LITstar::setPolicy(ParameterPolicyPtr policy)
    {
        if (!policy)
            throw ompl::Exception("LITstar: the policy must not be null");
        policy_ = std::move(policy);
        // The new policy's B until a solution (B is decided at improvements), and its psi_K until its first decision,
        // or throughout if it decides none: the previous policy's values are not carried over.
        if (!std::isfinite(bestCost_))
            batchSize_ = static_cast<unsigned int>(std::max(1, policy_->initialBatchSize()));
        if (!std::isfinite(bestCost_) || !policy_->decidesNeighbourFactor())
            neighbourFactor_ = policy_->initialNeighbourFactor();
        // getBatchSize() and the batch_size parameter (what OMPL's Benchmark records) report a fixed policy's B.
        if (policy_->name() == "fixed")
            fixedBatchSize_ = static_cast<unsigned int>(policy_->initialBatchSize());
    }
    const ParameterPolicyPtr &LITstar::getPolicy() const
    {
        return policy_;
    }
    void LITstar::setSeed(unsigned int seed)
    {
        seed_ = seed;
        seedSet_ = true;
    }
    unsigned int LITstar::getSeed() const
    {
        return seed_;
    }
    void LITstar::setMaxIterations(unsigned int iterations)
    {
        maxIterations_ = iterations;
    }
    unsigned int LITstar::getMaxIterations() const
    {
        return maxIterations_;
    }
    void LITstar::setMaxBatches(unsigned int batches)
    {
        maxBatches_ = batches;
    }
    unsigned int LITstar::getMaxBatches() const
    {
        return maxBatches_;
    }
    void LITstar::setTimeBudget(double seconds)
    {
        // A negative budget used to become 0, "no limit": the opposite of what a typo meant.
        if (!(seconds >= 0.0))
            throw ompl::Exception("LITstar: the time budget must be 0 (no limit) or more seconds, got " +
                                  detail::numberText(seconds));
        timeBudget_ = seconds;
    }
    double LITstar::getTimeBudget() const
    {
        return timeBudget_;
    }
    void LITstar::addListener(std::shared_ptr<PlannerListener> listener)
    {
        if (listener)
            listeners_.push_back(std::move(listener));
    }

    // ------------------------------------------------------------------------------------------------- clock
    double LITstar::planningTime() const
    {
        double total = accumulatedTime_;
        if (clockRunning_)
            total += std::chrono::duration<double>(Clock::now() - runningSince_).count();
        return total;
    }
    void LITstar::pauseClock()
    {
        if (clockRunning_)
        {
            accumulatedTime_ += std::chrono::duration<double>(Clock::now() - runningSince_).count();
            clockRunning_ = false;
        }
    }
    void LITstar::resumeClock()
    {
        if (!clockRunning_)
        {
            runningSince_ = Clock::now();
            clockRunning_ = true;
        }
    }

    // ------------------------------------------------------------------------------------------ setup, clear
    void LITstar::setup()
    {
        // Checked before Planner::setup() marks the planner as set up: solve() calls setup() only while it is not,
        // and a second solve() after the exception planned in an SO(2) or SE(2) space (a heap overflow).
        if (si_->getStateSpace()->getType() != ompl::base::STATE_SPACE_REAL_VECTOR)
            throw ompl::Exception("LITstar: needs a RealVectorStateSpace (its informed sampler and features are R^n)");
        checkObjective();
        Planner::setup();
    }

    void LITstar::checkObjective()
    {
        if (!pdef_)
            return;
        if (!pdef_->hasOptimizationObjective())
            pdef_->setOptimizationObjective(std::make_shared<ompl::base::PathLengthOptimizationObjective>(si_));
        else if (!std::dynamic_pointer_cast<ompl::base::PathLengthOptimizationObjective>(
                     pdef_->getOptimizationObjective()))
            throw ompl::Exception("LITstar: supports the path-length objective only");
    }

    void LITstar::setProblemDefinition(const ompl::base::ProblemDefinitionPtr &pdef)
    {
        const bool same = pdef == pdef_;  // the same problem again: keep solving it, as OMPL's planners do
        Planner::setProblemDefinition(pdef);
        if (!same)
            clear();
    }

    void LITstar::clear()
    {
        Planner::clear();
        if (forwardQueue_)
            forwardQueue_->clear();
        forwardQueue_.reset();
        graph_.reset();
        reverseQueue_ = {};
        problemInitialized_ = false;
        terminalsPending_ = false;
        batchLimitReached_ = false;
        bestCost_ = infinity;
        pruneDue_ = false;
        bestPathStates_.clear();
        rhoLocalBPending_ = false;
        rhoLocalBPath_.clear();
        batchSize_ = static_cast<unsigned int>(std::max(1, policy_->initialBatchSize()));
        neighbourFactor_ = policy_->initialNeighbourFactor();
        improvements_ = 0u;
        counters_ = LITstarCounters{};
        accumulatedTime_ = 0.0;
        clockRunning_ = false;
        statusMessage_.clear();
        firstSolutionMeasure_ = 0.0;
        warnedUnusableBatchSize_ = false;
        warnedUnusableFactor_ = false;
        reportedShortBatch_ = false;
        goalRead_.reset();
        startsRead_.clear();
        goalsGrow_ = false;
    }

    bool LITstar::finiteState(const ompl::base::State *state) const
    {
        std::vector<double> reals;
        si_->getStateSpace()->copyToReals(reals, state);
        return std::all_of(reals.begin(), reals.end(), [](double x) { return std::isfinite(x); });
    }

    std::vector<std::vector<double>> LITstar::problemStarts() const
    {
        std::vector<std::vector<double>> starts(pdef_->getStartStateCount());
        for (std::size_t i = 0u; i < starts.size(); ++i)
            si_->getStateSpace()->copyToReals(starts[i], pdef_->getStartState(i));
        return starts;
    }

    std::string LITstar::problemChange() const
    {
        // SimpleSetup::setGoalState replaces the goal object; a cleared one that only the problem held is gone.
        if (goalRead_.expired() || goalRead_.lock() != pdef_->getGoal())
            return "the goal was replaced or cleared";
        // Added, removed or replaced (SimpleSetup::setStartState); bit for bit, so that a start with a NaN
        // coordinate (left out when read) is the same start at the next solve().
        const std::vector<std::vector<double>> starts = problemStarts();
        const auto sameBits = [](const std::vector<double> &a, const std::vector<double> &b)
        {
            return a.size() == b.size() &&
                   (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
        };
        if (!std::equal(starts.begin(), starts.end(), startsRead_.begin(), startsRead_.end(), sameBits))
            return "the start states changed";
        // Every edge's check count, and the sparse-check progress kept per edge, are in steps of this resolution.
        const ompl::base::StateSpacePtr &space = si_->getStateSpace();
        if (space->getLongestValidSegmentLength() != longestValidSegment_ ||
            std::max(1u, space->getValidSegmentCountFactor()) != segmentCountFactor_)
            return "the state validity checking resolution changed";
        return {};
    }

    ompl::base::PlannerStatus LITstar::initializeProblem(const ompl::base::PlannerTerminationCondition &ptc)
    {
        statusMessage_.clear();
        startsRead_ = problemStarts();
        checkObjective();  // a problem set after setup() may have none (setup() is not called again)
        const ompl::base::GoalPtr &goal = pdef_->getGoal();
        if (!goal || !goal->hasType(ompl::base::GOAL_SAMPLEABLE_REGION))
        {
            statusMessage_ = "the goal is missing or not a sampleable goal region";
            return ompl::base::PlannerStatus::UNRECOGNIZED_GOAL_TYPE;
        }
        // Every valid start state is a root of the forward tree (nextStart() skips, with OMPL's warning, those
        // out of bounds or in collision).
        // A NaN coordinate passes OMPL's bounds check (every comparison with it is false) and may pass a user's
        // checker; its edges would then ask for NaN collision checks. Such states are left out here.
        const auto finite = [this](const ompl::base::State *state) { return finiteState(state); };
        std::size_t notFinite = 0u;
        std::vector<const ompl::base::State *> starts;
        while (const ompl::base::State *start = pis_.nextStart())
        {
            if (finite(start))
                starts.push_back(start);
            else
                ++notFinite;
        }
        if (starts.empty())
        {
            statusMessage_ = notFinite > 0u ? "the start state has a coordinate that is not a finite number" :
                                              "the start state is missing, out of bounds or in collision";
            return ompl::base::PlannerStatus::INVALID_START;
        }
        if (notFinite > 0u)
            OMPL_WARN("%s: left out %zu start state(s) with a coordinate that is not a finite number",
                      getName().c_str(), notFinite);
        notFinite = 0u;
        // A goal state or set is read to its end through PlannerInputStates: nextGoal() answers null (with OMPL's
        // warning, once per state) for a goal out of bounds or in collision. Any other region (OMPL's GoalSpace,
        // whose samples never end) is sampled here: at most MAX_GOAL_SAMPLES valid samples in at most 10 times as
        // many draws (reading them all filled memory before the clock started), and one line for the draws out of
        // bounds or in collision instead of OMPL's warning for each.
        std::vector<std::unique_ptr<ompl::base::State, std::function<void(ompl::base::State *)>>> owned;
        std::vector<const ompl::base::State *> goals;
        bool stoppedReading = false;  // a stop came while a goal region was sampled
        const auto keep = [&](const ompl::base::State *g)
        {
            if (!finite(g))
            {
                ++notFinite;
                return;
            }
            owned.emplace_back(si_->cloneState(g), [this](ompl::base::State *state) { si_->freeState(state); });
            goals.push_back(owned.back().get());
        };
        if (goal->hasType(ompl::base::GOAL_STATE) || goal->hasType(ompl::base::GOAL_STATES))
        {
            // As many as the set holds now: a GoalLazySamples (a goal set) grows while its thread samples. One
            // that holds none yet is waited for (until the termination condition), as OMPL's planners do.
            const auto *sampleable = goal->as<ompl::base::GoalSampleableRegion>();
            if (goal->hasType(ompl::base::GOAL_LAZY_SAMPLES) && sampleable->maxSampleCount() == 0u)
            {
                // Also no longer than the planner's own time budget allows (the wait is planning time).
                const double left = timeBudget_ - planningTime();
                const ompl::base::PlannerTerminationCondition wait =
                    timeBudget_ > 0.0 ? ompl::base::plannerOrTerminationCondition(
                                            ptc, ompl::base::timedPlannerTerminationCondition(std::max(0.0, left))) :
                                        ptc;
                if (const ompl::base::State *g = pis_.nextGoal(wait))
                    keep(g);
                else
                {
                    statusMessage_ = "the goal's sampler gave no valid goal state before the termination condition "
                                     "or the time budget";
                    return ompl::base::PlannerStatus::INVALID_GOAL;
                }
            }
            goalsGrow_ = goal->hasType(ompl::base::GOAL_LAZY_SAMPLES);  // read again at every batch
            const std::size_t members = sampleable->maxSampleCount();
            for (std::size_t read = goals.size(); read < members && pis_.haveMoreGoalStates(); ++read)
                if (const ompl::base::State *g = pis_.nextGoal())
                    keep(g);
        }
        else
        {
            goalsGrow_ = true;  // sampled again at every batch
            const auto *region = goal->as<ompl::base::GoalSampleableRegion>();
            const std::size_t limit = std::min<std::size_t>(region->maxSampleCount(), MAX_GOAL_SAMPLES);
            std::size_t draws = 0u;
            if (region->canSample())
            {
                std::unique_ptr<ompl::base::State, std::function<void(ompl::base::State *)>> scratch(
                    si_->allocState(), [this](ompl::base::State *state) { si_->freeState(state); });
                // The termination condition and the time budget are asked between draws, as
                // PlannerInputStates::nextGoal(ptc) does (a region mostly in collision with a slow checker held
                // solve() for all of them).
                for (; goals.size() < limit && draws < 10u * limit; ++draws)
                {
                    if (shouldStop())
                    {
                        stoppedReading = true;
                        break;
                    }
                    region->sampleGoal(scratch.get());
                    if (si_->satisfiesBounds(scratch.get()) && si_->isValid(scratch.get()))
                        keep(scratch.get());
                }
            }
            OMPL_INFORM("%s: planning to %zu goal samples of the goal region (%zu of %zu draws out of bounds or in "
                        "collision)",
                        getName().c_str(), goals.size(), draws - goals.size(), draws);
        }
        if (goals.empty() && stoppedReading)
        {
            statusMessage_ = "the termination condition or the time budget came before a valid sample of the goal "
                             "region";
            return ompl::base::PlannerStatus::TIMEOUT;
        }
        if (goals.empty())
        {
            statusMessage_ = notFinite > 0u ? "the goal state has a coordinate that is not a finite number" :
                                              "the goal state is missing, out of bounds or in collision";
            return ompl::base::PlannerStatus::INVALID_GOAL;
        }
        if (notFinite > 0u)
            OMPL_WARN("%s: left out %zu goal state(s) with a coordinate that is not a finite number",
                      getName().c_str(), notFinite);
        goalRead_ = goal;

        dimension_ = si_->getStateDimension();
        longestValidSegment_ = si_->getStateSpace()->getLongestValidSegmentLength();
        segmentCountFactor_ = std::max(1u, si_->getStateSpace()->getValidSegmentCountFactor());
        spaceMeasure_ = si_->getSpaceMeasure();
        if (interpolated_ == nullptr)
            interpolated_ = si_->allocState();
        point_.assign(dimension_, 0.0);
        bestPathStates_.clear();  // they belonged to the graph replaced here
        rhoLocalBPending_ = false;
        rhoLocalBPath_.clear();
        if (!seedSet_)
        {
            if (!seedSource_)
                seedSource_ = std::make_unique<ompl::RNG>();
            seed_ = static_cast<unsigned int>(seedSource_->uniformInt(1, std::numeric_limits<int>::max()));
        }
        graph_ = std::make_unique<litstar::RandomGeometricGraph>(si_, seed_);
        forwardQueue_ = std::make_unique<litstar::ForwardQueue>([this](litstar::Edge &edge) { computeKeys(edge); });
        graph_->setTerminals(starts, goals);
        terminalsPending_ = true;
        for (State *start : graph_->starts())
            start->costToCome_ = 0.0;
        firstSolutionMeasure_ = 0.0;
        batchSize_ = static_cast<unsigned int>(std::max(1, policy_->initialBatchSize()));
        neighbourFactor_ = policy_->initialNeighbourFactor();
        problemInitialized_ = true;
        return ompl::base::PlannerStatus::UNKNOWN;
    }

    // ------------------------------------------------------------------------------------------------- solve
    ompl::base::PlannerStatus LITstar::solve(const ompl::base::PlannerTerminationCondition &ptc)
    {
        if (!isSetup())
            setup();
        if (!pdef_)
        {
            statusMessage_ = "no problem definition is set";
            return ompl::base::PlannerStatus::ABORT;
        }
        if (problemInitialized_)
        {
            // The search belongs to the start and goal it read: a changed problem is solved anew, as a new problem
            // definition is (it went on with the old ones and filed their path as an exact solution).
            const std::string change = problemChange();
            if (!change.empty())
            {
                OMPL_INFORM("%s: %s since the problem was read: the search starts over (the problem definition's "
                            "solutions, of the former problem, are cleared)",
                            getName().c_str(), change.c_str());
                clear();
                pdef_->clearSolutionPaths();  // else the former, possibly cheaper, path stayed its best solution
            }
        }
        struct Running  // the termination condition and the clock belong to this call, also if it throws
        {
            LITstar &planner;
            Running(LITstar &p, const ompl::base::PlannerTerminationCondition &ptc) : planner(p)
            {
                planner.ptc_ = &ptc;
                planner.resumeClock();
            }
            ~Running()
            {
                planner.pauseClock();
                planner.ptc_ = nullptr;
            }
            Running(const Running &) = delete;
            Running &operator=(const Running &) = delete;
        };
        if (!problemInitialized_)
        {
            ompl::base::PlannerStatus status;
            {
                // Reading the problem is planning time (a goal region's draws, a goal set's wait, the graph), as
                // it is for OMPL's planners, timed from solve() on: it was left off the clock, and a goal
                // region's draws did not count in LIT*'s t_init.
                accumulatedTime_ = 0.0;  // a new problem's clock (also after a read that threw)
                const Running reading(*this, ptc);
                status = initializeProblem(ptc);
            }
            if (status != ompl::base::PlannerStatus::UNKNOWN)
            {
                accumulatedTime_ = 0.0;  // nothing was planned: the next solve() reads the problem anew
                pis_.restart();  // the next solve() reads the start and goals again (the start was taken already)
                if (status == ompl::base::PlannerStatus::TIMEOUT)  // a stop while reading: no error in the problem
                    OMPL_INFORM("%s: %s", getName().c_str(), statusMessage_.c_str());
                else
                    OMPL_ERROR("%s: %s", getName().c_str(), statusMessage_.c_str());
                return status;
            }
        }
        // At every solve(): the checker may have been replaced since the last one (and is held while used).
        // Exactly our checker: a subclass may override isValid(), which the fast path would not call on edges.
        const ompl::base::StateSpace *space = si_->getStateSpace().get();
        const ompl::base::StateValidityChecker *checker = si_->getStateValidityChecker().get();
        boxChecker_ = typeid(*space) == typeid(ompl::base::RealVectorStateSpace) && checker != nullptr &&
                              typeid(*checker) == typeid(BoxWorldValidityChecker) ?
                          std::static_pointer_cast<const BoxWorldValidityChecker>(si_->getStateValidityChecker()) :
                          nullptr;
        // Likewise the motion validator: a custom one is asked about every edge the resolution's points pass.
        const ompl::base::MotionValidator *validator = si_->getMotionValidator().get();
        customMotionValidator_ =
            validator != nullptr && dynamic_cast<const ompl::base::DiscreteMotionValidator *>(validator) == nullptr;
        batchLimitReached_ = false;
        statusMessage_.clear();
        {
            const Running running(*this, ptc);
            while (!shouldStop() && !batchLimitReached_ && !solutionCannotImprove() &&
                   (maxIterations_ == 0u || counters_.iterations < maxIterations_))
            {
                ++counters_.iterations;
                iterate();
            }
        }
        if (goalsGrow_ && atStraightLineBound() && graph_->goals().size() >= MAX_GOALS)
            OMPL_INFORM("%s: stopped at the straight line to the nearest of its %zu goal samples (the most it takes "
                        "from a goal region or a growing goal set), so a better goal of it may exist",
                        getName().c_str(), graph_->goals().size());
        if (std::isfinite(bestCost_) && !pdef_->hasExactSolution())
            addBestPathToProblem();  // the caller cleared the solutions since this planner found its best path
        if (!std::isfinite(bestCost_))  // OMPL calls every stop without a solution a timeout: say which it was
        {
            if (maxIterations_ != 0u && counters_.iterations >= maxIterations_)
                statusMessage_ = "no solution within the iteration limit (" + std::to_string(maxIterations_) + ")";
            else if (batchLimitReached_)
                statusMessage_ = "no solution within the batch limit (" + std::to_string(maxBatches_) + ")";
            else if (timeBudget_ > 0.0 && planningTime() >= timeBudget_)
                statusMessage_ = "no solution within the time budget";
            else
                statusMessage_ = "no solution when the termination condition stopped the planner";
        }
        return std::isfinite(bestCost_) ? ompl::base::PlannerStatus::EXACT_SOLUTION :
                                          ompl::base::PlannerStatus::TIMEOUT;
    }

    bool LITstar::shouldStop() const
    {
        return (ptc_ != nullptr && (*ptc_)()) || (timeBudget_ > 0.0 && planningTime() >= timeBudget_);
    }

    bool LITstar::goalsMayGrow() const
    {
        if (!goalsGrow_ || graph_->goals().size() >= MAX_GOALS)
            return false;
        // Only the goal that was read (solve() starts over for a replaced or cleared one).
        const std::shared_ptr<ompl::base::Goal> goal = goalRead_.lock();
        if (goal == nullptr || goal != pdef_->getGoal())
            return false;
        // A goal set grows while its thread samples, or until what it holds is read; a region until its samples end.
        if (const auto *lazy = dynamic_cast<const ompl::base::GoalLazySamples *>(goal.get()))
            return lazy->isSampling() || pis_.haveMoreGoalStates();
        const auto *region = goal->as<ompl::base::GoalSampleableRegion>();
        return region->canSample() && graph_->goals().size() < region->maxSampleCount();
    }

    std::size_t LITstar::addGoalSamples()
    {
        if (!goalsMayGrow())
            return 0u;
        const std::size_t wanted = std::min(GOAL_SAMPLES_PER_BATCH, MAX_GOALS - graph_->goals().size());
        // Only goals whose straight line from a start is shorter than the best cost; of a region's samples, only those
        // nearer to a start than every goal so far: samples behind an obstacle would otherwise pile up, each one more
        // root of every reverse search (100 batches on NP in R^16 with a small goal box took 8 times as long), while
        // the nearest goals are those that shorten a path that reaches the region in a straight line. A goal set's
        // new members are the user's own goals: each is read.
        const ompl::base::GoalPtr &goal = pdef_->getGoal();  // the goal read (goalsMayGrow())
        const bool lazy = goal->hasType(ompl::base::GOAL_LAZY_SAMPLES);
        double nearest = lazy ? std::numeric_limits<double>::infinity() : graph_->sampler().minimumCost();
        std::vector<std::unique_ptr<ompl::base::State, std::function<void(ompl::base::State *)>>> owned;
        std::vector<const ompl::base::State *> fresh;
        // \e check: a region's draw, whose validity is asked only once it is near enough (pis_ checked the set's).
        const auto keep = [&](const ompl::base::State *g, bool check)
        {
            if (!finiteState(g))
                return;
            double straight = std::numeric_limits<double>::infinity();
            for (const State *start : graph_->starts())
                straight = std::min(straight, si_->distance(start->raw_, g));
            if (!(straight < nearest && straight < bestCost_))
                return;
            if (check && !(si_->satisfiesBounds(g) && si_->isValid(g)))
                return;
            nearest = lazy ? nearest : straight;
            owned.emplace_back(si_->cloneState(g), [this](ompl::base::State *state) { si_->freeState(state); });
            fresh.push_back(owned.back().get());
        };
        if (lazy)  // what its sampling thread added since the last read
        {
            for (std::size_t read = 0u; fresh.size() < wanted && read < 10u * wanted && pis_.haveMoreGoalStates();
                 ++read)
            {
                if (const ompl::base::State *g = pis_.nextGoal())  // null: a member out of bounds or in collision
                    keep(g, false);
            }
        }
        else
        {
            const auto *region = goal->as<ompl::base::GoalSampleableRegion>();
            std::unique_ptr<ompl::base::State, std::function<void(ompl::base::State *)>> scratch(
                si_->allocState(), [this](ompl::base::State *state) { si_->freeState(state); });
            for (std::size_t draws = 0u; fresh.size() < wanted && draws < 10u * wanted; ++draws)
            {
                region->sampleGoal(scratch.get());
                keep(scratch.get(), true);
            }
        }
        graph_->addGoals(fresh);
        return fresh.size();
    }

    bool LITstar::atStraightLineBound() const
    {
        // Within rounding of the straight line (Eigen's norm and OMPL's distance may differ in the last bits).
        return std::isfinite(bestCost_) && bestCost_ <= graph_->sampler().minimumCost() * (1.0 + 1e-12);
    }

    bool LITstar::solutionCannotImprove() const
    {
        if (!std::isfinite(bestCost_))
            return false;
        // The straight line to the goals read so far bounds the cost only when no other goal can come.
        if (atStraightLineBound() && !goalsMayGrow())
            return true;
        const auto &objective = pdef_->getOptimizationObjective();
        return objective && objective->isSatisfied(ompl::base::Cost(bestCost_));
    }

    void LITstar::iterate()
    {
        if (terminalsPending_)  // the first iteration, or start-goal lines that a stop left unchecked
        {
            connectTerminals();
            // No batch is drawn after a stop (the next solve() draws it).
            if (!terminalsPending_ && counters_.batches == 0u && !solutionCannotImprove() && !shouldStop())
                improveApproximation();
        }
        else if (continueReverseSearch())
            reverseStep();
        else if (continueForwardSearch())
            forwardStep();
        else if (maxBatches_ != 0u && counters_.batches >= maxBatches_)
            batchLimitReached_ = true;
        else
            improveApproximation();
    }

    bool LITstar::continueReverseSearch() const
    {
        if (reverseQueue_.empty())
            return false;
        const double reverseKey = reverseQueue_.top().key;
        if (reverseKey >= bestCost_)
            return false;
        const litstar::Edge *front = forwardQueue_->top();
        if (front == nullptr)
        {
            // EIT* goes on with the reverse search here (its expansions may still hand edges to the forward search).
            // Measured on the development queries (lit bench, seeds 3000-3019, instance 7, half budgets, all three
            // policies): the same first solutions on all six scenarios, but on rrd8 a few hundred more sparse checks
            // before them and 4 of 60 runs unsolved within the budget. With no forward edge left, a new batch first.
            return false;
        }
        // The front edge's target has its final cost-to-go once the reverse search's key reaches the edge's
        // lower bound (A* from the goal with the consistent heuristic g_lb).
        return reverseKey < front->lowerBoundKey;
    }

    bool LITstar::continueForwardSearch() const
    {
        const litstar::Edge *front = forwardQueue_->top();
        if (front == nullptr)
            return false;
        if (forwardQueue_->isEffortFirst())
            return std::isfinite(front->effortKey);
        return front->lowerBoundKey < bestCost_;
    }

    // -------------------------------------------------------------------------------------------- edge checks
    unsigned int &LITstar::checkedDepth(State *a, State *b)
    {
        return a->id_ < b->id_ ? a->checkedDepth_[b->id_] : b->checkedDepth_[a->id_];
    }

    bool LITstar::isWhitelisted(const State *a, const State *b) const
    {
        return a->whitelist_.count(b->id_) > 0u;
    }
    bool LITstar::isBlacklisted(const State *a, const State *b) const
    {
        return a->blacklist_.count(b->id_) > 0u;
    }
    void LITstar::whitelist(State *a, State *b)
    {
        a->whitelist_.insert(b->id_);
        b->whitelist_.insert(a->id_);
    }
    void LITstar::blacklist(State *a, State *b)
    {
        a->blacklist_.insert(b->id_);
        b->blacklist_.insert(a->id_);
        ++counters_.edgesInvalid;
        // A queued forward edge over it (either way) would only be popped and dropped; left queued, its finite key
        // could hold the front and decide when the searches hand over.
        if (forwardQueue_)
            forwardQueue_->removePair(a, b);
    }

    double LITstar::remainingChecks(const State *a, const State *b) const
    {
        if (isWhitelisted(a, b))
            return 0.0;
        const double interior = std::max(0.0, static_cast<double>(segmentCount(a, b)) - 1.0);
        const State *from = a->id_ < b->id_ ? a : b;
        const State *to = a->id_ < b->id_ ? b : a;
        const auto it = from->checkedDepth_.find(to->id_);
        const unsigned int depth = it == from->checkedDepth_.end() ? 0u : it->second;
        const double done = depth >= 63u ? interior : std::ldexp(1.0, static_cast<int>(depth)) - 1.0;
        return std::max(0.0, interior - done);
    }

    unsigned int LITstar::segmentCount(const State *a, const State *b) const
    {
        // As OMPL's StateSpace::validSegmentCount: the same resolution for every planner in a comparison.
        const double count =
            static_cast<double>(segmentCountFactor_) * std::ceil(graph_->distance(a, b) / longestValidSegment_);
        if (!(count < 2147483648.0))  // also NaN: the point indices are unsigned int
            throw ompl::Exception("LITstar: an edge of length " + detail::numberText(graph_->distance(a, b)) +
                                  " needs " + detail::numberText(count) +
                                  " collision checks at this state validity checking resolution, more than 2^31: "
                                  "use a coarser resolution");
        return static_cast<unsigned int>(count);
    }

    bool LITstar::checkEdge(State *a, State *b, unsigned int depth)
    {
        // Points are i/n along the canonical direction (smaller id first), visited level by level in bisection
        // order, so a sparse check of depth D is exactly the first 2^D - 1 points of the full check. Level l holds
        // the midpoints of the intervals that l - 1 halvings of [0, n] leave (integer halving, left to right; an
        // interval shorter than 2 has no midpoint). Each level is walked depth-first from the whole edge instead of
        // keeping the previous level's intervals: the memory is the recursion's (at most 32 levels), not one interval
        // per check, and the walk adds fewer steps than the level's own checks.
        State *from = a->id_ < b->id_ ? a : b;
        State *to = a->id_ < b->id_ ? b : a;
        unsigned int &done = checkedDepth(from, to);
        if (done == fullCheck)
            return true;
        const unsigned int segments = segmentCount(from, to);
        // Levels 1 .. done were checked and each held a point (a level without one ends the check: whitelisted). An
        // invalid point leaves the depth as it was (the edge is blacklisted).
        unsigned int level = done;
        while (level < depth)
        {
            std::size_t points = 0u;
            if (!checkLevel(from, to, segments, 0u, segments, level + 1u, points))
                return false;
            if (points == 0u)
            {
                if (customMotionValidator_)
                {
                    ++counters_.collisionChecks;  // one call, however many checks the validator makes
                    if (!si_->checkMotion(from->raw_, to->raw_))
                        return false;
                }
                done = fullCheck;
                whitelist(from, to);
                rekeyForwardEdges(from, to);
                return true;
            }
            ++level;
        }
        const bool progressed = level != done;
        done = level;
        if (progressed)
            rekeyForwardEdges(from, to);
        return true;
    }

    void LITstar::rekeyForwardEdges(State *a, State *b)
    {
        // A forward edge's effort key counts the checks left on the edge itself: fewer now, either direction.
        if (forwardQueue_)
            forwardQueue_->updatePair(a, b);
    }

    bool LITstar::checkLevel(const State *from, const State *to, unsigned int segments, unsigned int lo,
                             unsigned int hi, unsigned int level, std::size_t &points)
    {
        if (hi - lo < 2u)
            return true;
        const unsigned int mid = lo + (hi - lo) / 2u;
        if (level > 1u)
            return checkLevel(from, to, segments, lo, mid, level - 1u, points) &&
                   checkLevel(from, to, segments, mid, hi, level - 1u, points);
        ++points;
        ++counters_.collisionChecks;
        const double t = static_cast<double>(mid) / static_cast<double>(segments);
        if (boxChecker_ != nullptr)
        {
            litstar::interpolateAsOmpl(from->coordinates_, to->coordinates_, t, point_.data(), dimension_);
            return boxChecker_->isValidCounted(point_.data());
        }
        si_->getStateSpace()->interpolate(from->raw_, to->raw_, t, interpolated_);
        return si_->isValid(interpolated_);
    }

    // ----------------------------------------------------------------------------------------------- searches
    void LITstar::computeKeys(litstar::Edge &edge) const
    {
        const double toGo = edge.target->reverseCost(reverseTag_);
        const double effort = edge.target->reverseEffort(reverseTag_);
        const double cost = graph_->distance(edge.source, edge.target);
        edge.lowerBoundKey = edge.source->costToCome_ + cost + toGo;
        if (!std::isfinite(effort))
            edge.effortKey = infinity;
        else
        {
            // The remaining checks on the edge itself, estimated from its length and sparse-check progress.
            edge.effortKey = effort + remainingChecks(edge.source, edge.target);
        }
    }

    void LITstar::collectNeighbours(State *state)
    {
        const auto nearest = graph_->neighbours(state, currentK_);
        auto &out = neighbours_;
        auto &distances = neighbourDistances_;
        out.assign(nearest.begin(), nearest.end());
        distances.assign(nearest.distances(), nearest.distances() + nearest.size());
        // Listed states carry the current stamp (a search of the list per addition was quadratic in k).
        const std::size_t stamp = ++collectStamp_;
        for (State *other : out)
            other->collectMark_ = stamp;
        auto addUnique = [&](State *other) {
            if (other != nullptr && other->collectMark_ != stamp)
            {
                other->collectMark_ = stamp;
                out.push_back(other);
                distances.push_back(graph_->distance(state, other));
            }
        };
        // The k-nearest relation is not symmetric; the edges the searches use are. Without the reverse direction the
        // reverse search (which expands from the goal side) and the forward search would search each other's
        // transposed graph, and the cost-to-go of the reverse search would not bound the forward search's paths. (Only
        // the lists computed so far are made symmetric: a sample never expanded adds no edges of its own.)
        const auto &incoming = graph_->incomingNeighbours(state);
        const auto &incomingDistances = graph_->incomingDistances(state);
        for (std::size_t i = 0; i < incoming.size(); ++i)
        {
            State *other = incoming[i];
            if (other->collectMark_ != stamp)
            {
                other->collectMark_ = stamp;
                out.push_back(other);
                distances.push_back(incomingDistances[i]);  // distance(other, state): distance(state, other)'s
            }
        }
        addUnique(state->forwardParent_);
        for (State *child : state->forwardChildren_)
            addUnique(child);
        addUnique(state->reverseParent(reverseTag_));
    }

    void LITstar::connectExpandedNeighbours(State *state)
    {
        for (std::size_t i = 0; i < neighbours_.size(); ++i)
        {
            State *other = neighbours_[i];
            if (isBlacklisted(state, other))
                continue;
            const double distance = neighbourDistances_[i];
            // Reverse search: other -> state (towards the goal through other).
            if (!state->isGoal_ && other != state->reverseParent(reverseTag_))
            {
                const double costToGo = other->reverseCost(reverseTag_) + distance;
                const double key = costToGo + state->costToComeLowerBound_;
                if (costToGo < state->reverseCost(reverseTag_) && key < bestCost_)
                    reverseQueue_.push(ReverseEdge{key, costToGo, other, state});
            }
            // Forward search: other -> state (from the start through other).
            if (!state->isStart_ && !other->isGoal_ && other != state->forwardParent_ && other->isInForwardTree())
            {
                const double costToCome = other->costToCome_ + distance;
                if (costToCome < state->costToCome_ && costToCome + state->costToGoLowerBound_ < bestCost_)
                    forwardQueue_->insert(other, state);
            }
        }
    }

    void LITstar::restartReverseSearch()
    {
        ++reverseTag_;
        ++counters_.reverseRestarts;
        reverseQueue_ = {};
        for (State *goal : graph_->goals())
        {
            goal->reverseTag_ = reverseTag_;
            goal->reverseCost_ = 0.0;
            goal->reverseEffort_ = 0.0;
            goal->reverseParent_ = nullptr;
        }
        for (State *goal : graph_->goals())
            expandReverse(goal);
        forwardQueue_->updateAll();
    }

    void LITstar::expandReverse(State *state)
    {
        if (state->isStart_)
            return;  // the reverse search only has to reach the start
        collectNeighbours(state);
        connectExpandedNeighbours(state);
        offerReverseEdges(state);
    }

    void LITstar::offerReverseEdges(State *state)
    {
        state->reverseK_ = currentK_;
        const double costToGo = state->reverseCost_;
        for (std::size_t i = 0; i < neighbours_.size(); ++i)
        {
            State *other = neighbours_[i];
            if (other == state->reverseParent_ || other->isGoal_ || isBlacklisted(state, other))
                continue;
            const double cost = costToGo + neighbourDistances_[i];
            if (cost >= other->reverseCost(reverseTag_))
                continue;
            const double key = cost + other->costToComeLowerBound_;
            if (key >= bestCost_)
                continue;
            reverseQueue_.push(ReverseEdge{key, cost, state, other});
        }
    }

    void LITstar::reverseStep()
    {
        ++counters_.reverseSteps;
        const ReverseEdge edge = reverseQueue_.top();
        reverseQueue_.pop();
        State *source = edge.source;
        State *target = edge.target;
        const double cost = source->reverseCost(reverseTag_) + graph_->distance(source, target);
        if (cost >= target->reverseCost(reverseTag_) || cost + target->costToComeLowerBound_ >= bestCost_ ||
            isBlacklisted(source, target))
            return;
        if (!isWhitelisted(source, target))
        {
            ++counters_.edgesSparselyChecked;
            if (!checkEdge(source, target, sparseDepth_))
            {
                blacklist(source, target);
                return;
            }
        }
        target->reverseTag_ = reverseTag_;
        target->reverseCost_ = cost;
        target->reverseEffort_ = source->reverseEffort_ + remainingChecks(source, target);
        target->reverseParent_ = source;
        forwardQueue_->updateIncoming(target);
        expandReverse(target);
    }

    void LITstar::expandForward(State *state)
    {
        if (state->isGoal_)
            return;  // a path through a goal never improves a solution
        ++counters_.expansions;
        currentK_ = adaptiveNeighborSize(state);
        collectNeighbours(state);
        connectExpandedNeighbours(state);
        // The reverse search expanded this state with the k of its time (the last decided one). A policy that
        // decided a larger k since lists neighbours here that the reverse search was never offered from it: their
        // cost-to-go through this state stayed unknown (only the edges into it were offered), and forward edges
        // into them were ordered as if the new edge did not exist. (A constant psi_K keeps one k per batch.)
        if (!state->isStart_ && state->reverseTag_ == reverseTag_ && std::isfinite(state->reverseCost_) &&
            currentK_ > state->reverseK_)
            offerReverseEdges(state);
        for (std::size_t i = 0; i < neighbours_.size(); ++i)
        {
            State *other = neighbours_[i];
            if (other == state->forwardParent_ || other->isStart_ || isBlacklisted(state, other))
                continue;
            if (other->forwardParent_ == state)
            {
                forwardQueue_->insert(state, other);  // re-traverses the kept forward tree
                continue;
            }
            const double costToCome = state->costToCome_ + neighbourDistances_[i];
            if (costToCome >= other->costToCome_ || costToCome + other->costToGoLowerBound_ >= bestCost_)
                continue;
            forwardQueue_->insert(state, other);
        }
    }

    void LITstar::forwardStep()
    {
        ++counters_.forwardSteps;
        const litstar::Edge edge = forwardQueue_->pop();
        State *source = edge.source;
        State *target = edge.target;
        if (target->forwardParent_ == source)
        {
            expandForward(target);
            return;
        }
        const double edgeCost = graph_->distance(source, target);
        const double costToCome = source->costToCome_ + edgeCost;
        // An edge queued before the reverse search's sparse check found it invalid: checking it again only
        // counted it twice (it is never a reverse-tree edge: the reverse search skips blacklisted edges).
        if (costToCome >= target->costToCome_ || costToCome + target->costToGoLowerBound_ >= bestCost_ ||
            isBlacklisted(source, target))
            return;
        if (!isWhitelisted(source, target))
        {
            ++counters_.edgesEvaluated;
            if (!checkEdge(source, target, fullCheck))
            {
                blacklist(source, target);
                if (source->reverseParent(reverseTag_) == target || target->reverseParent(reverseTag_) == source)
                {
                    // An edge of the reverse tree (either direction): the reverse search was too
                    // optimistic here; check its edges more densely (d <- 2d + 1).
                    ++sparseDepth_;
                    restartReverseSearch();
                }
                return;
            }
        }
        rewire(source, target, edgeCost);
        checkForImprovedSolution();
        expandForward(target);
    }

    void LITstar::rewire(State *parent, State *child, double edgeCost)
    {
        if (child->forwardParent_ != nullptr)
        {
            auto &siblings = child->forwardParent_->forwardChildren_;
            siblings.erase(std::remove(siblings.begin(), siblings.end(), child), siblings.end());
        }
        child->forwardParent_ = parent;
        child->parentEdgeCost_ = edgeCost;
        parent->forwardChildren_.push_back(child);
        propagateCostToCome(child);
    }

    void LITstar::propagateCostToCome(State *state)
    {
        std::vector<State *> stack{state};
        while (!stack.empty())
        {
            State *current = stack.back();
            stack.pop_back();
            current->costToCome_ = current->forwardParent_->costToCome_ + current->parentEdgeCost_;
            forwardQueue_->updateOutgoing(current);
            stack.insert(stack.end(), current->forwardChildren_.begin(), current->forwardChildren_.end());
        }
    }

    void LITstar::detachFromForwardTree(State *state)
    {
        forwardQueue_->removeEdgesOf(state);
        if (state->forwardParent_ != nullptr)
        {
            auto &siblings = state->forwardParent_->forwardChildren_;
            siblings.erase(std::remove(siblings.begin(), siblings.end(), state), siblings.end());
            state->forwardParent_ = nullptr;
        }
        std::vector<State *> stack(state->forwardChildren_.begin(), state->forwardChildren_.end());
        state->forwardChildren_.clear();
        state->costToCome_ = infinity;
        while (!stack.empty())
        {
            State *current = stack.back();
            stack.pop_back();
            stack.insert(stack.end(), current->forwardChildren_.begin(), current->forwardChildren_.end());
            current->forwardChildren_.clear();
            current->forwardParent_ = nullptr;
            current->costToCome_ = infinity;
        }
    }

    void LITstar::connectTerminals()
    {
        // In an empty R^16 world the start was never among the goal's k nearest: LIT* stayed 28 % above the straight
        // line for its whole budget while BIT* and AIT* returned it at once. A blocked line usually fails at its
        // first checks (bisection order: the midpoint first). Nearest goal first: the first free line is the best.
        // With several starts, every start-goal line, nearest pair first.
        std::vector<std::pair<State *, State *>> pairs;
        for (State *start : graph_->starts())
            for (State *goal : graph_->goals())
                pairs.emplace_back(start, goal);
        std::stable_sort(pairs.begin(), pairs.end(), [&](const auto &a, const auto &b) {
            return graph_->distance(a.first, a.second) < graph_->distance(b.first, b.second);
        });
        terminalsPending_ = false;
        for (const auto &[start, goal] : pairs)
        {
            const double cost = graph_->distance(start, goal);
            if (cost >= bestCost_)
                break;
            if (shouldStop())
            {
                terminalsPending_ = true;  // the next iteration (the next solve()) checks the lines left
                break;
            }
            if (isBlacklisted(start, goal) || isWhitelisted(start, goal))
                continue;
            ++counters_.edgesEvaluated;
            if (!checkEdge(start, goal, fullCheck))
            {
                blacklist(start, goal);
                continue;
            }
            if (cost < goal->costToCome_)
                rewire(start, goal, cost);
            break;
        }
        checkForImprovedSolution();
    }

    void LITstar::checkForImprovedSolution()
    {
        State *best = nullptr;
        for (State *goal : graph_->goals())
            if (goal->costToCome_ < bestCost_ && (best == nullptr || goal->costToCome_ < best->costToCome_))
                best = goal;
        if (best != nullptr)
            registerSolution(best);
    }

    void LITstar::registerSolution(State *goal)
    {
        const bool first = !std::isfinite(bestCost_);
        bestCost_ = goal->costToCome_;
        pruneDue_ = true;
        ++improvements_;
        if (first)
            firstSolutionMeasure_ = getMeasure();
        // The best path's samples are pinned: a prune never removes them. (Their straight-line bounds cannot exceed
        // the path's cost in exact arithmetic, but in floating point a sample on a straight stretch could by an
        // ulp, and bestPath() and the features read these states.) Pinned states are never pruned, so the old
        // path's states are all still alive here.
        for (State *s : bestPathStates_)
            s->pinned_ = false;
        bestPathStates_.clear();
        for (State *s = goal; s != nullptr; s = s->forwardParent_)
        {
            s->pinned_ = true;
            bestPathStates_.push_back(s);
        }
        std::reverse(bestPathStates_.begin(), bestPathStates_.end());
        keepPathForRhoLocalB();  // before the caller's code below, which may throw; the B decision may compute it

        addBestPathToProblem();
        std::vector<const ompl::base::State *> states;
        for (State *s : bestPathStates_)
            states.push_back(s->raw_);
        if (first)
            forwardQueue_->setEffortFirst(false);  // epsilon: infinity -> 1 (before the caller's code, which may throw)
        if (const auto &callback = pdef_->getIntermediateSolutionCallback())
            callback(this, states, ompl::base::Cost(bestCost_));

        SolutionEvent event;
        event.time = planningTime();
        event.cost = bestCost_;
        event.pathStates = bestPathStates_.size();
        event.improvement = improvements_;
        event.iteration = counters_.iterations;
        notifyListeners([&event](PlannerListener &listener) { listener.onSolution(event); });
        adaptiveBatchsize();
    }

    void LITstar::addBestPathToProblem()
    {
        auto path = std::make_shared<ompl::geometric::PathGeometric>(si_);
        for (State *s : bestPathStates_)
            path->append(s->raw_);
        // With its cost and whether it satisfies the objective, as OMPL's optimizing planners file theirs
        // (PlannerSolution::cost_ and ProblemDefinition::hasOptimizedSolution() read them).
        ompl::base::PlannerSolution solution(path);
        solution.setPlannerName(getName());
        const ompl::base::OptimizationObjectivePtr &objective = pdef_->getOptimizationObjective();
        const ompl::base::Cost cost(bestCost_);
        solution.setOptimized(objective, cost, objective && objective->isSatisfied(cost));
        pdef_->addSolutionPath(solution);
    }

    void LITstar::improveApproximation()
    {
        forwardQueue_->clear();
        reverseQueue_ = {};
        if (addGoalSamples() > 0u)
            connectTerminals();  // a new goal may lie in a straight line from a start
        std::size_t pruned = 0u;
        if (pruneDue_ && std::isfinite(bestCost_))
        {
            pruned = graph_->prune(bestCost_, [this](State *state) { detachFromForwardTree(state); });
            ++counters_.prunes;
        }
        pruneDue_ = false;
        counters_.prunedSamples += pruned;
        const std::size_t checksBefore = graph_->validDraws() + graph_->invalidDraws();
        const std::size_t added = graph_->addBatch(batchSize_, bestCost_, [this] { return shouldStop(); });
        const std::size_t draws = graph_->validDraws() + graph_->invalidDraws() - checksBefore;
        counters_.collisionChecks += draws;
        if (graph_->lastBatchCapped() && !reportedShortBatch_)
        {
            reportedShortBatch_ = true;
            OMPL_INFORM("%s: batch %zu ended with %zu of its %u samples, after %zu draws (%zu per sample at most): "
                        "the informed set is almost all in collision (reported once per problem)",
                        getName().c_str(), static_cast<std::size_t>(counters_.batches + 1u), added, batchSize_, draws,
                        litstar::RandomGeometricGraph::MAX_DRAWS_PER_SAMPLE);
        }
        counters_.validSamples = graph_->validDraws();
        counters_.invalidSamples = graph_->invalidDraws();
        ++counters_.batches;
        sparseDepth_ = 1u;
        currentK_ = neighbourCount(neighbourFactor_);
        // rho_local,B of this batch is read only by the psi_K decisions made before the next solution (which
        // computes its own): most batches make none. Its inputs are fixed here (the samples do not change until the
        // next batch; the path and the radius are kept), and it is computed at the first decision that reads it.
        // They are kept whatever the policy: a policy set between two solve() calls may read them.
        keepPathForRhoLocalB();
        restartReverseSearch();
        for (State *start : graph_->starts())
            if (start->costToGoLowerBound_ < bestCost_)  // a start farther from every goal cannot improve it
                expandForward(start);

        BatchEvent event;
        event.batch = counters_.batches;
        event.batchSize = batchSize_;
        event.validSamples = graph_->numValid();
        event.invalidSamples = graph_->numInvalid();
        event.prunedSamples = pruned;
        event.time = planningTime();
        notifyListeners([&event](PlannerListener &listener) { listener.onBatch(event); });
    }

    // ----------------------------------------------------------------------------------- LIT* decisions
    double LITstar::getMeasure() const
    {
        return informedMeasure(dimension_, bestCost_, graph_->sampler().minimumCost(), spaceMeasure_);
    }

    std::size_t LITstar::neighbourCount(double neighbourFactor) const
    {
        const double n = static_cast<double>(dimension_);
        const double q = std::max(static_cast<double>(graph_->numValid()), 2.0);
        const double k = std::ceil(rewireFactor_ * neighbourFactor * (1.0 + 1.0 / n) * std::log(q));
        if (!(k >= 1.0))  // NaN too (a cast of NaN or of a double beyond size_t is undefined)
            return 1u;
        return static_cast<std::size_t>(std::min(k, 1e12));
    }

    std::vector<const ompl::base::State *> LITstar::bestPathRawStates() const
    {
        std::vector<const ompl::base::State *> path;
        path.reserve(bestPathStates_.size());
        for (const State *s : bestPathStates_)
            path.push_back(s->raw_);
        return path;
    }

    bool LITstar::featuresObserved() const
    {
        return std::any_of(listeners_.begin(), listeners_.end(),
                           [](const auto &listener) { return listener->observesFeatures(); });
    }

    void LITstar::keepPathForRhoLocalB()
    {
        rhoLocalBPending_ = !bestPathStates_.empty();
        if (rhoLocalBPending_)
        {
            rhoLocalBPath_ = bestPathRawStates();
            rhoLocalBRadius_ = graph_->radius(rewireFactor_, getMeasure());
        }
        else
            rhoLocalBPath_.clear();
    }

    double LITstar::pathLocalRatio() const
    {
        return graph_->localRatioCalc(bestPathRawStates(), nullptr, graph_->radius(rewireFactor_, getMeasure())).first;
    }

    Features LITstar::computeFeatures(const ompl::base::State *centre) const
    {
        Features features;
        if (!graph_)
            return features;
        features.rhoGlobal = graph_->ratioCalc();
        const double informed = getMeasure();
        features.measure = std::isfinite(bestCost_) ? measureFeature(dimension_, informed, spaceMeasure_) : 1.0;
        const std::vector<const ompl::base::State *> path = bestPathRawStates();
        const double radius = graph_->radius(rewireFactor_, informed);
        const auto [localB, localK] = graph_->localRatioCalc(path, centre ? centre : graph_->start()->raw_, radius);
        features.rhoLocalB = localB;
        features.rhoLocalK = localK;
        return features;
    }

    DecisionContext LITstar::makeContext(DecisionKind kind) const
    {
        DecisionContext context;
        context.kind = kind;
        context.dimension = dimension_;
        context.hasSolution = std::isfinite(bestCost_);
        context.cost = bestCost_;
        context.improvements = improvements_;
        context.pathStates = bestPathStates_.size();
        context.planningTime = planningTime();
        context.informedMeasure = getMeasure();
        context.spaceMeasure = spaceMeasure_;
        context.firstSolutionMeasure = firstSolutionMeasure_;
        context.minimumCost = graph_->sampler().minimumCost();
        context.expansions = counters_.expansions;
        context.batches = counters_.batches;
        context.checks = counters_.collisionChecks;
        context.features.rhoGlobal = graph_->ratioCalc();
        context.features.measure =
            context.hasSolution ? measureFeature(dimension_, context.informedMeasure, spaceMeasure_) : 1.0;
        if (bestPathStates_.empty())
            context.features.rhoLocalB = context.features.rhoGlobal;
        else if (!policy_->needsFeatures() && !featuresObserved())
            context.features.rhoLocalB = std::numeric_limits<double>::quiet_NaN();  // not computed
        else
        {
            if (rhoLocalBPending_)
            {
                rhoLocalB_ = graph_->localRatioCalc(rhoLocalBPath_, nullptr, rhoLocalBRadius_).first;
                rhoLocalBPending_ = false;
                rhoLocalBPath_.clear();
            }
            context.features.rhoLocalB = rhoLocalB_;
        }
        context.features.rhoLocalK = context.features.rhoGlobal;
        return context;
    }

    double LITstar::decide(DecisionContext &context)
    {
        const bool pause = policy_->pausesClock();
        if (pause)
            pauseClock();
        const double value = policy_->decide(context);
        if (pause)
            resumeClock();
        return value;
    }

    void LITstar::warnUnusableDecision(DecisionKind kind, double value)
    {
        bool &warned = kind == DecisionKind::BatchSize ? warnedUnusableBatchSize_ : warnedUnusableFactor_;
        if (!warned)
            OMPL_WARN("%s: the %s policy answered %g for %s; the value in use is kept (further unusable answers "
                      "for it in this problem are not reported)",
                      getName().c_str(), policy_->name().c_str(), value,
                      kind == DecisionKind::BatchSize ? "B" : "psi_K");
        warned = true;
    }

    void LITstar::adaptiveBatchsize()
    {
        const bool observed = featuresObserved();
        if (policy_->needsFeatures() || observed)
        {
            rhoLocalBPending_ = false;  // computed below for this solution's path, with the clock paused if need be
            rhoLocalBPath_.clear();
        }
        DecisionContext context = makeContext(DecisionKind::BatchSize);  // rho_local,B: NaN if nobody reads it
        if (policy_->needsFeatures() || observed)
        {
            // A policy that ignores the features (fixed, fit) does not pay for them: they are
            // computed only for the listeners then, with the clock paused.
            const bool observeOnly = !policy_->needsFeatures() && clockRunning_;
            if (observeOnly)
                pauseClock();
            rhoLocalB_ = pathLocalRatio();
            if (observeOnly)
                resumeClock();
            context.features.rhoLocalB = rhoLocalB_;
        }
        const double value = decide(context);
        // Any ParameterPolicy can be plugged in: a whole number of at least 1 and at most INT_MAX (a cast of
        // 5e9 wrapped to 705032704), and an answer that is not a number keeps the batch size in use.
        if (std::isfinite(value))
            batchSize_ = static_cast<unsigned int>(
                std::clamp(std::round(value), 1.0, static_cast<double>(std::numeric_limits<int>::max())));
        else
            warnUnusableDecision(DecisionKind::BatchSize, value);
        ++counters_.batchDecisions;
        DecisionEvent event;
        event.kind = DecisionKind::BatchSize;
        event.features = context.features;
        event.value = static_cast<double>(batchSize_);
        event.policy = policy_->name();
        event.time = planningTime();
        event.iteration = counters_.iterations;
        notifyListeners([&event](PlannerListener &listener) { listener.onDecision(event); });
    }

    std::size_t LITstar::adaptiveNeighborSize(State *centre)
    {
        if (policy_->decidesNeighbourFactor() && (counters_.expansions - 1u) % decisionInterval_ == 0u)
        {
            DecisionContext context = makeContext(DecisionKind::NeighbourFactor);
            if (policy_->needsFeatures())
            {
                const double informed = context.informedMeasure;
                const double ratio = graph_->localRatio(centre->raw_, graph_->radius(rewireFactor_, informed));
                context.features.rhoLocalK = ratio >= 0.0 ? ratio : context.features.rhoGlobal;
            }
            const double value = decide(context);
            if (std::isfinite(value) && value > 0.0)
                neighbourFactor_ = value;
            else
                warnUnusableDecision(DecisionKind::NeighbourFactor, value);  // keeps the factor in use
            ++counters_.neighbourDecisions;
            const std::size_t k = neighbourCount(neighbourFactor_);
            DecisionEvent event;
            event.kind = DecisionKind::NeighbourFactor;
            event.features = context.features;
            event.value = neighbourFactor_;
            event.neighbours = k;
            event.policy = policy_->name();
            event.time = planningTime();
            event.iteration = counters_.iterations;
            notifyListeners([&event](PlannerListener &listener) { listener.onDecision(event); });
            return k;
        }
        return neighbourCount(neighbourFactor_);
    }

    // ------------------------------------------------------------------------------------------- reporting
    std::vector<std::vector<double>> LITstar::bestPath() const
    {
        std::vector<std::vector<double>> path;
        for (const State *s : bestPathStates_)
        {
            std::vector<double> x;
            si_->getStateSpace()->copyToReals(x, s->raw_);
            path.push_back(std::move(x));
        }
        return path;
    }

    void LITstar::getPlannerData(ompl::base::PlannerData &data) const
    {
        Planner::getPlannerData(data);
        if (!graph_)
            return;
        for (const State *start : graph_->starts())
            data.addStartVertex(ompl::base::PlannerDataVertex(start->raw_, static_cast<int>(start->id_)));
        for (const State *goal : graph_->goals())
            data.addGoalVertex(ompl::base::PlannerDataVertex(goal->raw_, static_cast<int>(goal->id_)));
        for (const auto &state : graph_->states())
            if (state->forwardParent_ != nullptr)
                data.addEdge(ompl::base::PlannerDataVertex(state->forwardParent_->raw_,
                                                           static_cast<int>(state->forwardParent_->id_)),
                             ompl::base::PlannerDataVertex(state->raw_, static_cast<int>(state->id_)),
                             ompl::base::PlannerDataEdge(),
                             ompl::base::Cost(graph_->distance(state->forwardParent_, state.get())));
    }
}  // namespace lit
