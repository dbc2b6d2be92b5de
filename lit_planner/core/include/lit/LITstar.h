#pragma once
/** \file LITstar.h
 *  \brief LIT* (Learning-based Informed Trees): an EIT*-class asymmetric bidirectional search whose batch size
 *  B and neighbour factor psi_K come from a ParameterPolicy fed with obstacle features. */

#include "lit/BoxWorld.h"
#include "lit/ParameterPolicy.h"
#include "lit/PlannerListener.h"
#include "lit/litstar/ForwardQueue.h"
#include "lit/litstar/RandomGeometricGraph.h"

#include <ompl/base/Planner.h>
#include <ompl/util/Exception.h>
#include <ompl/util/RandomNumbers.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <queue>
#include <string>
#include <utility>
#include <vector>

namespace lit
{
    /** \brief Counters of one planning problem. */
    struct LITstarCounters
    {
        std::size_t iterations{0u};
        std::size_t batches{0u};
        std::size_t validSamples{0u};
        std::size_t invalidSamples{0u};
        std::size_t prunedSamples{0u};
        /** \brief Prune passes: one at the first batch after each new solution. */
        std::size_t prunes{0u};
        /** \brief States checked by the planner (samples and edge points). */
        std::size_t collisionChecks{0u};
        /** \brief Edges fully collision-checked by the forward search. */
        std::size_t edgesEvaluated{0u};
        /** \brief Sparse checks by the reverse search, and edges found invalid (either search). */
        std::size_t edgesSparselyChecked{0u};
        std::size_t edgesInvalid{0u};
        std::size_t reverseSteps{0u};
        std::size_t forwardSteps{0u};
        std::size_t reverseRestarts{0u};
        std::size_t expansions{0u};
        std::size_t batchDecisions{0u};
        std::size_t neighbourDecisions{0u};
    };

    class LITstar : public ompl::base::Planner
    {
    public:
        /** \brief Goal samples taken at the start of a problem from a goal region other than a goal state or set
         *  (OMPL's GoalSpace, say; a goal set is read whole). Many goals slow the search down (each batch restarts
         *  the reverse search at every goal): on NP in R^4 with goals drawn in a 0.1-wide box, 30 batches took about
         *  11 s with 1000 goals (one-off). */
        static constexpr std::size_t MAX_GOAL_SAMPLES = 100u;
        /** \brief Goals drawn at each later batch from such a region (or read from a goal set that grows), kept only when
         *  their straight line from a start is shorter than the best cost: BIT* and AIT* draw new goals as they go. */
        static constexpr std::size_t GOAL_SAMPLES_PER_BATCH = 10u;
        /** \brief The most goals taken from a region or a growing goal set in all. */
        static constexpr std::size_t MAX_GOALS = 4u * MAX_GOAL_SAMPLES;

        explicit LITstar(const ompl::base::SpaceInformationPtr &si);
        ~LITstar() override;

        void setup() override;
        void clear() override;
        /** \brief A new problem also clears the graph, trees and solution of the previous one (OMPL's base class
         *  keeps them, and solve() then went on with the old start and goal). */
        void setProblemDefinition(const ompl::base::ProblemDefinitionPtr &pdef) override;
        /** \brief Plans until \e ptc, the iteration, batch or time limit, or an optimal solution; a later call goes on
         *  with the same search. When the problem definition's start states changed since they were read (added,
         *  removed or replaced, compared coordinate for coordinate) or its goal object was replaced or cleared, the
         *  search starts over as after clear(), and the problem definition's solutions, which belong to the former
         *  problem, are cleared too (also any the caller added since). A goal changed in place (a state added to the
         *  same GoalStates) is not seen: replace the goal, or clear(). */
        ompl::base::PlannerStatus solve(const ompl::base::PlannerTerminationCondition &ptc) override;
        void getPlannerData(ompl::base::PlannerData &data) const override;

        /** \brief Batch size of the fixed policy (EIT*'s B). */
        void setBatchSize(unsigned int batchSize);
        unsigned int getBatchSize() const;
        /** \brief Rewire factor eta of the k-nearest RGG and of the feature radius. */
        void setRewireFactor(double factor);
        double getRewireFactor() const;
        /** \brief psi_K is decided every \e interval expansions (1: at every expansion). */
        void setDecisionInterval(unsigned int interval);
        unsigned int getDecisionInterval() const;
        /** \brief Policy by name: "fixed" or "fit" (tensor and external policies: setPolicy()). */
        void setPolicyName(const std::string &name);
        std::string getPolicyName() const;
        void setPolicy(ParameterPolicyPtr policy);
        const ParameterPolicyPtr &getPolicy() const;
        /** \brief Seed of the planner's own sampler RNG for every problem. Without it each problem draws one from
         *  an ompl::RNG (OMPL's global seed decides); getSeed() gives the seed of the current problem (0 before the
         *  first one). */
        void setSeed(unsigned int seed);
        unsigned int getSeed() const;
        /** \brief Stop after this many iterations / batches in total over the solve() calls of a problem, until
         *  clear() or a new problem (0: no limit). */
        void setMaxIterations(unsigned int iterations);
        unsigned int getMaxIterations() const;
        void setMaxBatches(unsigned int batches);
        unsigned int getMaxBatches() const;
        /** \brief Stop after this much planner time in total over the solve() calls of a problem, until clear() or a
         *  new problem (s, external-policy time excluded; 0: no limit; negative: ompl::Exception). */
        void setTimeBudget(double seconds);
        double getTimeBudget() const;

        /** \brief Receives solution, decision and batch events. */
        void addListener(std::shared_ptr<PlannerListener> listener);

        const LITstarCounters &counters() const
        {
            return counters_;
        }
        /** \brief Planner time (s) spent in solve so far, external-policy time excluded. */
        double planningTime() const;
        /** \brief Best cost (infinite without a solution) and the best path's coordinates. */
        double bestCost() const
        {
            return bestCost_;
        }
        std::vector<std::vector<double>> bestPath() const;
        /** \brief Features at \e centre (nullptr: the start) in the current search state. */
        Features computeFeatures(const ompl::base::State *centre = nullptr) const;
        /** \brief Why the last solve returned what it did: a refused start or goal, or which limit stopped it without
         *  a solution (empty when it has one). */
        const std::string &statusMessage() const
        {
            return statusMessage_;
        }
        /** \brief Current B and psi_K: the policy's initial ones until it decides them (B at a solution, psi_K at an
         *  expansion), also after clear() and after setPolicy() (psi_K there also after a solution when the new
         *  policy decides none). */
        unsigned int currentBatchSize() const
        {
            return batchSize_;
        }
        double currentNeighbourFactor() const
        {
            return neighbourFactor_;
        }
        /** \brief Why the last value refused through params().setParam() was refused (its setter's message). */
        const std::string &refusedParameter() const
        {
            return refusedParameter_;
        }
        void noteRefusedParameter(const std::string &why)
        {
            refusedParameter_ = why;
        }
        /** \brief The sample sets (read-only, for tests and introspection); ompl::Exception before a problem is set
         *  up (before the first solve, after clear() or a failed setup). */
        const litstar::RandomGeometricGraph &graph() const
        {
            if (!graph_)
                throw ompl::Exception("LITstar: no problem is set up yet: graph() is there after solve() began one");
            return *graph_;
        }

    private:
        /** \brief Sets up the problem on the first call of solve; returns a status other than UNKNOWN on failure. */
        ompl::base::PlannerStatus initializeProblem(const ompl::base::PlannerTerminationCondition &ptc);
        void iterate();
        /** \brief Gives the problem the path-length objective if it has none; refuses any other objective. */
        void checkObjective();
        /** \brief The termination condition of the running solve() or the time budget says stop (also checked
         *  while a batch is drawn: in a nearly blocked space one batch can take many draws). */
        bool shouldStop() const;
        /** \brief No better solution exists: the best cost reached the straight-line lower bound, or the
         *  objective's cost threshold is met. */
        bool solutionCannotImprove() const;
        /** \brief The best cost is the straight line of the nearest start-goal pair (within rounding). */
        bool atStraightLineBound() const;
        /** \brief More goals may still be read (see goalsGrow_). */
        bool goalsMayGrow() const;
        /** \brief At a new batch: up to GOAL_SAMPLES_PER_BATCH more goals that may improve the solution, from a goal
         *  region or a growing goal set; returns how many were added. */
        std::size_t addGoalSamples();
        /** \brief Every coordinate of \e state is a finite number. */
        bool finiteState(const ompl::base::State *state) const;
        /** \brief The problem definition's start states, as coordinates. */
        std::vector<std::vector<double>> problemStarts() const;
        /** \brief What changed in the problem definition since the problem was read (its start states, or its goal
         *  object replaced), or an empty string. */
        std::string problemChange() const;
        bool continueReverseSearch() const;
        bool continueForwardSearch() const;
        void reverseStep();
        void forwardStep();
        /** \brief Prune, sample a batch of B valid states, restart the reverse search, re-seed the forward queue. */
        void improveApproximation();
        /** \brief Before the first batch: the straight lines from the start to the goals, nearest goal first, each
         *  checked in full, up to the first free one (the first search of BIT*, AIT* and EIT*, over a graph of the
         *  start and the goals alone). A free line is a solution; a blocked one is black-listed. */
        void connectTerminals();
        /** \brief A fixed policy of batch size \e batchSize, with the current fixed policy's psi_K if there is one. */
        ParameterPolicyPtr fixedPolicy(unsigned int batchSize) const;
        void restartReverseSearch();
        void expandReverse(litstar::State *state);
        /** \brief Offers the reverse search the edges from \a state (in the reverse tree) to the neighbours just
         *  collected (neighbours_), and records their k as state->reverseK_. */
        void offerReverseEdges(litstar::State *state);
        void expandForward(litstar::State *state);
        /** \brief Edge checks: sparse to a bisection depth, or full; both reuse earlier checks. */
        bool checkEdge(litstar::State *a, litstar::State *b, unsigned int depth);
        /** \brief Re-keys the queued forward edges between \e a and \e b after a check changed what is left. */
        void rekeyForwardEdges(litstar::State *a, litstar::State *b);
        unsigned int &checkedDepth(litstar::State *a, litstar::State *b);
        unsigned int segmentCount(const litstar::State *a, const litstar::State *b) const;
        /** \brief Checks the points of bisection level \p level inside [lo, hi] (counted in \p points), left to
         * right; false at the first invalid one. */
        bool checkLevel(const litstar::State *from, const litstar::State *to, unsigned int segments, unsigned int lo,
                        unsigned int hi, unsigned int level, std::size_t &points);
        double remainingChecks(const litstar::State *a, const litstar::State *b) const;
        bool isWhitelisted(const litstar::State *a, const litstar::State *b) const;
        bool isBlacklisted(const litstar::State *a, const litstar::State *b) const;
        void whitelist(litstar::State *a, litstar::State *b);
        void blacklist(litstar::State *a, litstar::State *b);
        void computeKeys(litstar::Edge &edge) const;
        void rewire(litstar::State *parent, litstar::State *child, double edgeCost);
        void propagateCostToCome(litstar::State *state);
        void detachFromForwardTree(litstar::State *state);
        void checkForImprovedSolution();
        /** \brief Hand the best path to the problem definition. */
        void addBestPathToProblem();
        void registerSolution(litstar::State *goal);
        /** \brief Neighbours for either search: the k nearest, the samples that have \e state among their k nearest,
         *  and its tree relatives, into neighbours_, with their distances from \e state in neighbourDistances_. */
        void collectNeighbours(litstar::State *state);
        /** \brief Hands the edges between \e state and its \e neighbours to the searches in the direction towards
         *  \e state: a neighbour already in the reverse tree may lower state's cost-to-go, one already in the forward
         *  tree may lower its cost-to-come. Needed because an edge becomes known only when one of its endpoints'
         *  neighbour list is computed, possibly after the other endpoint was expanded. */
        void connectExpandedNeighbours(litstar::State *state);
        /** \brief Algorithm 1's decisions. */
        void adaptiveBatchsize();
        /** \brief Warns (once per problem) of a policy answer the planner cannot use. */
        void warnUnusableDecision(DecisionKind kind, double value);
        std::size_t adaptiveNeighborSize(litstar::State *centre);
        double getMeasure() const;
        /** \brief rho_local,B alone: the mean local ratio along the best path (rho_global without one). */
        double pathLocalRatio() const;
        /** \brief A listener reads the features of B decisions. */
        bool featuresObserved() const;
        /** \brief Keeps the best path and the radius for rho_local,B, to be computed when a decision first reads
         *  it (nothing to keep without a path). */
        void keepPathForRhoLocalB();
        /** \brief The OMPL states of the best path (empty without a solution). */
        std::vector<const ompl::base::State *> bestPathRawStates() const;
        double decide(DecisionContext &context);
        DecisionContext makeContext(DecisionKind kind) const;
        std::size_t neighbourCount(double neighbourFactor) const;
        void pauseClock();
        void resumeClock();
        /** \brief Calls notify(listener) for every listener with the planner clock paused: what an
         *  observer does with an event (a ROS node publishes it) is not planning time. */
        template <typename Notify>
        void notifyListeners(Notify &&notify)
        {
            if (listeners_.empty())
                return;
            const bool running = clockRunning_;
            pauseClock();
            for (auto &listener : listeners_)
                notify(*listener);
            if (running)
                resumeClock();
        }

        // Parameters.
        unsigned int fixedBatchSize_{100u};
        double rewireFactor_{1.001};
        unsigned int decisionInterval_{1u};
        unsigned int seed_{0u};
        /** setSeed() was called: every problem uses seed_. Otherwise each problem draws its seed from seedSource_,
         *  which OMPL seeds (ompl::RNG::setSeed() makes the runs reproducible, and a benchmark's runs differ). It is
         *  made at the first draw: an ompl::RNG takes a seed from OMPL's global sequence, which a planner given its
         *  seed must leave to the planners made after it. */
        bool seedSet_{false};
        std::unique_ptr<ompl::RNG> seedSource_;
        unsigned int maxIterations_{0u};
        unsigned int maxBatches_{0u};
        double timeBudget_{0.0};
        ParameterPolicyPtr policy_;
        std::vector<std::shared_ptr<PlannerListener>> listeners_;

        // Search state.
        std::unique_ptr<litstar::RandomGeometricGraph> graph_;
        std::unique_ptr<litstar::ForwardQueue> forwardQueue_;
        struct ReverseEdge
        {
            double key;
            double cost;
            litstar::State *source;
            litstar::State *target;
            bool operator>(const ReverseEdge &other) const
            {
                return key != other.key ? key > other.key : cost > other.cost;
            }
        };
        std::priority_queue<ReverseEdge, std::vector<ReverseEdge>, std::greater<>> reverseQueue_;
        unsigned int reverseTag_{1u};
        /** \brief Bisection depth of the reverse search's sparse checks (d = 2^depth - 1 checks). */
        unsigned int sparseDepth_{1u};
        bool problemInitialized_{false};
        /** \brief Start-goal lines not checked yet: set for new terminals, cleared by a connectTerminals() that
         *  ran to its end (a stop within it left the farther goals' lines unchecked for good). */
        bool terminalsPending_{false};
        bool batchLimitReached_{false};
        /** \brief The termination condition of the running solve() (null outside it). */
        const ompl::base::PlannerTerminationCondition *ptc_{nullptr};
        std::string statusMessage_;
        std::string refusedParameter_;
        unsigned int dimension_{0u};
        double longestValidSegment_{1.0};
        /** The state space's valid segment count factor (OMPL's validSegmentCount multiplies by it). */
        unsigned int segmentCountFactor_{1u};
        /** The space information's motion validator is not OMPL's DiscreteMotionValidator: an edge that passes the
         *  state checks of a full check is also given to si->checkMotion() (the validator may refuse motions whose
         *  states are all valid). */
        bool customMotionValidator_{false};
        double spaceMeasure_{0.0};
        double bestCost_{std::numeric_limits<double>::infinity()};
        /** A solution was registered since the last prune: the next batch prunes. With the cost unchanged a prune
         * finds nothing (every sample since the last one was drawn from the same informed set, and the pinned path
         * is the same) yet costs O(samples): it rebuilt the packed coordinate arrays every batch. */
        bool pruneDue_{false};
        std::vector<litstar::State *> bestPathStates_;
        /** \brief rho_local,B of the best path over the current samples, unless pending. */
        mutable double rhoLocalB_{0.0};
        /** \brief rho_local,B is still to be computed (from rhoLocalBPath_ and rhoLocalBRadius_, the path and radius
         *  kept at the batch's start, or at a solution whose B decision did not compute it) when a decision first
         *  reads it. */
        mutable bool rhoLocalBPending_{false};
        mutable std::vector<const ompl::base::State *> rhoLocalBPath_;
        double rhoLocalBRadius_{0.0};
        unsigned int batchSize_{100u};
        double neighbourFactor_{M_E};
        /** \brief An unusable policy answer (not a number; psi_K <= 0) was reported for this problem, per parameter. */
        bool warnedUnusableBatchSize_{false};
        bool reportedShortBatch_{false};  // a batch that its draw limit ended (once per problem)
        /** \brief The goal read when the problem was initialised (a replaced one starts the search over). */
        std::weak_ptr<ompl::base::Goal> goalRead_;
        /** \brief The problem definition's start states (coordinates) when the problem was read. */
        std::vector<std::vector<double>> startsRead_;
        /** \brief The goal is a region to sample or a goal set that may grow: more goals are read at every batch (up to
         *  MAX_GOALS), and until then the straight line to those read is no lower bound. */
        bool goalsGrow_{false};
        bool warnedUnusableFactor_{false};
        std::size_t currentK_{1u};
        std::size_t improvements_{0u};
        /** \brief Informed-set measure at this problem's first solution (0 before it; FIT*'s reference). */
        double firstSolutionMeasure_{0.0};
        LITstarCounters counters_;
        ompl::base::State *interpolated_{nullptr};
        /** \brief The box-world checker when it is the problem's and the space is OMPL's own R^n space: checkLevel()
         *  then interpolates as RealVectorStateSpace::interpolate does and calls the checker directly (the same
         *  points, answers and call count, without two virtual calls and an OMPL state per check); else null. */
        std::shared_ptr<const BoxWorldValidityChecker> boxChecker_;
        std::vector<double> point_;
        /** \brief The neighbours of the state being expanded and their distances (collectNeighbours(); kept to avoid
         *  two allocations per expansion). The k nearest take their distances from the graph's cache, which holds
         *  distance()'s values to the bit: each neighbour's distance was computed up to three times per expansion. */
        std::vector<litstar::State *> neighbours_;
        std::vector<double> neighbourDistances_;
        /** \brief Stamp of the current collectNeighbours() (see State::collectMark_). */
        std::size_t collectStamp_{0u};

        // Planner clock: wall time in solve minus external-policy time.
        using Clock = std::chrono::steady_clock;
        double accumulatedTime_{0.0};
        Clock::time_point runningSince_;
        bool clockRunning_{false};
    };
}  // namespace lit
