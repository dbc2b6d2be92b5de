// Python bindings of the LIT* core: worlds, LIT* with every policy, and OMPL 1.5.2's baselines on the same
// problem and validity checker. solve() releases the GIL; Python callables re-acquire it.
#include "lit/BoxWorld.h"
#include "lit/InformedMeasure.h"
#include "lit/LITstar.h"
#include "lit/LookupTensor.h"
#include "lit/ParameterPolicy.h"
#include "lit/TskActor.h"

#include <ompl/base/PlannerTerminationCondition.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/geometric/PathGeometric.h>
#include <ompl/geometric/planners/informedtrees/ABITstar.h>
#include <ompl/geometric/planners/informedtrees/AITstar.h>
#include <ompl/geometric/planners/informedtrees/BITstar.h>
#include <ompl/geometric/planners/rrt/InformedRRTstar.h>
#include <ompl/geometric/planners/rrt/RRTConnect.h>
#include <ompl/util/Console.h>
#include <ompl/util/RandomNumbers.h>

#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <optional>
#include <algorithm>
#include <atomic>
#include <mutex>
#include <thread>
#include <tuple>

namespace py = pybind11;
using namespace lit;

namespace
{
    /** \brief A query as data; every solve builds its own space, checker and problem definition. */
    /** \brief Set from another thread to end a running solve early (a node that is shutting down). */
    struct CancelFlag
    {
        std::shared_ptr<std::atomic<bool>> flag{std::make_shared<std::atomic<bool>>(false)};
    };

    struct Query
    {
        BoxWorld world;
        std::vector<double> start;
        std::vector<double> goal;
        double resolution{5e-6};
        /** Edges checked exactly against the boxes (custom worlds), not at the resolution alone. */
        bool exactEdges{false};
    };

    const std::vector<std::string> &plannerNames()
    {
        static const std::vector<std::string> names{"litstar", "aitstar", "bitstar", "abitstar", "irrtstar", "rrtconnect"};
        return names;
    }

    ompl::base::PlannerPtr makeOmplPlanner(const std::string &name, const ompl::base::SpaceInformationPtr &si)
    {
        if (name == "aitstar")
            return std::make_shared<ompl::geometric::AITstar>(si);
        if (name == "bitstar")
            return std::make_shared<ompl::geometric::BITstar>(si);
        if (name == "abitstar")
            return std::make_shared<ompl::geometric::ABITstar>(si);
        if (name == "irrtstar")
            return std::make_shared<ompl::geometric::InformedRRTstar>(si);
        if (name == "rrtconnect")
            return std::make_shared<ompl::geometric::RRTConnect>(si);
        throw py::value_error("unknown planner '" + name + "' (known: litstar, aitstar, bitstar, abitstar, irrtstar, rrtconnect)");
    }

    void checkFeatures(double x, double y, double z)
    {
        if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
            throw py::value_error("lookup point (" + std::to_string(x) + ", " + std::to_string(y) + ", " +
                                  std::to_string(z) + ") is not finite");
    }

    std::string statusName(ompl::base::PlannerStatus status)
    {
        switch (status.operator ompl::base::PlannerStatus::StatusType())
        {
            case ompl::base::PlannerStatus::EXACT_SOLUTION: return "exact_solution";
            case ompl::base::PlannerStatus::APPROXIMATE_SOLUTION: return "approximate_solution";
            case ompl::base::PlannerStatus::TIMEOUT: return "timeout";
            case ompl::base::PlannerStatus::INVALID_START: return "invalid_start";
            case ompl::base::PlannerStatus::INVALID_GOAL: return "invalid_goal";
            case ompl::base::PlannerStatus::UNRECOGNIZED_GOAL_TYPE: return "unrecognized_goal_type";
            case ompl::base::PlannerStatus::CRASH: return "crash";
            case ompl::base::PlannerStatus::ABORT: return "abort";
            default: return "unknown";
        }
    }

    /** \brief A KeyboardInterrupt or SystemExit in an external policy's callback, carried out of the solve and
     *  raised again in Python (see the exception translator in the module). */
    class PythonPolicyAbort : public PolicyAbort
    {
    public:
        explicit PythonPolicyAbort(py::error_already_set error)
          : PolicyAbort(error.what()), error_(std::move(error))
        {
        }
        void restore() const
        {
            py::error_already_set copy = error_;
            copy.restore();
        }

    private:
        py::error_already_set error_;
    };

    /** \brief Records LIT*'s events, and forwards them to an optional Python listener. */
    class RecordingListener : public PlannerListener
    {
    public:
        RecordingListener(py::object listener, std::shared_ptr<const BoxWorldValidityChecker> checker,
                          bool observesFeatures)
          : listener_(std::move(listener)), checker_(std::move(checker)), observesFeatures_(observesFeatures)
        {
        }
        bool observesFeatures() const override
        {
            return observesFeatures_;
        }
        void onSolution(const SolutionEvent &event) override
        {
            solutions.push_back(event);
            solutionChecks.push_back(checker_->calls());
            forward("on_solution", [&] { return py::cast(event); });
        }
        void onDecision(const DecisionEvent &event) override
        {
            decisions.push_back(event);
            forward("on_decision", [&] { return py::cast(event); });
        }
        void onBatch(const BatchEvent &event) override
        {
            batches.push_back(event);
            forward("on_batch", [&] { return py::cast(event); });
        }
        std::vector<SolutionEvent> solutions;
        /** \brief The validity checker's calls when each solution was reported. */
        std::vector<std::uint64_t> solutionChecks;
        std::vector<DecisionEvent> decisions;
        std::vector<BatchEvent> batches;

    private:
        template <typename Make>
        void forward(const char *method, Make make)
        {
            if (!hasListener_)
                return;
            py::gil_scoped_acquire gil;
            if (py::hasattr(listener_, method))
                listener_.attr(method)(make());
        }
        py::object listener_;
        bool hasListener_{!listener_.is_none()};
        std::shared_ptr<const BoxWorldValidityChecker> checker_;
        bool observesFeatures_;
    };

    py::dict decisionDict(const DecisionEvent &event)
    {
        py::dict d;
        d["kind"] = toString(event.kind);
        d["value"] = event.value;
        d["neighbours"] = event.neighbours;
        d["policy"] = event.policy;
        d["time"] = event.time;
        d["iteration"] = event.iteration;
        d["rho_global"] = event.features.rhoGlobal;
        d["rho_local_b"] = event.features.rhoLocalB;
        d["rho_local_k"] = event.features.rhoLocalK;
        d["measure"] = event.features.measure;
        return d;
    }

    /** \brief One point of a run's cost curve, with the validity checks made up to it. */
    struct Improvement
    {
        double time;
        double cost;
        std::uint64_t checks;
    };

    /** \brief Start or goal problems that every planner should report the same way, without planning. */
    std::string checkTerminal(const char *what, const std::vector<double> &x, const BoxProblem &problem)
    {
        for (double v : x)
            if (!std::isfinite(v))
                return std::string(what) + " has a non-finite coordinate";
        // Compared exactly: OMPL's satisfiesBounds allows an ulp or so outside, which the box check then called
        // "in collision".
        const auto &bounds = problem.si->getStateSpace()->as<ompl::base::RealVectorStateSpace>()->getBounds();
        for (std::size_t i = 0; i < x.size(); ++i)
            if (x[i] < bounds.low[i] || x[i] > bounds.high[i])
                return std::string(what) + " is out of bounds";
        if (!problem.checker->isValidPoint(x.data()))
            return std::string(what) + " is in collision";
        return "";
    }

    /** \brief The finite number that all of \e text spells, if it spells one (strtod). */
    std::optional<double> parseNumber(const std::string &text)
    {
        char *end = nullptr;
        const double value = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0' || !std::isfinite(value))
            return std::nullopt;
        return value;
    }

    /** \brief The longest time solve() takes, s (as lit_planner.planning.MAX_TIME). */
    constexpr double maxSolveTime = 1e9;
    /** \brief Planner parameters that solve() sets from its own arguments: not taken in its params. */
    const std::map<std::string, std::string> argumentParams{{"seed", "seed"},
                                                            {"time_budget", "time"},
                                                            {"policy", "policy"},
                                                            {"max_iterations", "max_iterations"},
                                                            {"max_batches", "max_batches"}};

    py::dict solveQuery(const Query &query, const std::string &plannerName, double time, ParameterPolicyPtr policy,
                        unsigned int seed, unsigned int maxIterations, unsigned int maxBatches,
                        const std::map<std::string, std::string> &params, py::object listenerObject,
                        const CancelFlag *cancel, bool features)
    {
        // Asked by LIT* every iteration and while it draws a batch, by OMPL's planners as they do.
        const std::shared_ptr<std::atomic<bool>> cancelled = cancel != nullptr ? cancel->flag : nullptr;
        const ompl::base::PlannerTerminationCondition cancelCondition =
            cancelled ? ompl::base::PlannerTerminationCondition([cancelled] { return cancelled->load(); }) :
                        ompl::base::plannerNonTerminatingCondition();
        // inf ended an OMPL planner at once (as a timeout) and gave LIT* no limit at all.
        if (!(std::isfinite(time) && time >= 0.0))
            throw py::value_error("solve needs a finite time >= 0 in seconds, got " + std::to_string(time));
        if (!(time > 0.0) && maxIterations == 0u && maxBatches == 0u)
            throw py::value_error("solve needs a positive time, max_iterations or max_batches");
        // OMPL's time-based stop counts nanoseconds in 64 bits: from about 9.2e9 s on its planners stopped at once.
        if (time > maxSolveTime)
            throw py::value_error("solve's time is at most 1e9 s, got " + std::to_string(time));
        for (const auto &[key, argument] : argumentParams)
            if (params.count(key) != 0u)  // it would override the argument, which the result reports
                throw py::value_error("give '" + key + "' as solve's " + argument + " argument, not in params");
        BoxProblem problem = makeBoxProblem(query.world, query.start, query.goal, query.resolution, query.exactEdges);

        py::dict result;
        result["planner"] = plannerName;
        result["seed"] = seed;
        std::string message = checkTerminal("start", query.start, problem);
        std::string status;
        if (message.empty())
        {
            message = checkTerminal("goal", query.goal, problem);
            if (!message.empty())
                status = "invalid_goal";
        }
        else
            status = "invalid_start";

        ompl::base::PlannerPtr planner;
        std::shared_ptr<LITstar> litstar;
        auto recorder = std::make_shared<RecordingListener>(listenerObject, problem.checker, features);
        std::vector<Improvement> improvements;
        double elapsed = 0.0;
        if (status.empty())
        {
            if (plannerName == "litstar")
            {
                litstar = std::make_shared<LITstar>(problem.si);
                litstar->setSeed(seed);
                if (policy)
                    litstar->setPolicy(policy);
                litstar->setMaxIterations(maxIterations);
                litstar->setMaxBatches(maxBatches);
                litstar->setTimeBudget(time > 0.0 ? time : 0.0);
                litstar->addListener(recorder);
                planner = litstar;
            }
            else
            {
                if (policy)
                    throw py::value_error("policies apply to litstar only, not to " + plannerName);
                if (!listenerObject.is_none())  // it was ignored without a word
                    throw py::value_error("a listener is called by litstar only; " + plannerName + " calls none");
                if (maxIterations != 0u || maxBatches != 0u || !(time > 0.0))
                    throw py::value_error(plannerName + " stops on time only: give a positive time");
                planner = makeOmplPlanner(plannerName, problem.si);
            }
            for (const auto &[key, value] : params)
            {
                if (!planner->params().hasParam(key))
                {
                    // Checked here: OMPL's setParam would also log an error of its own.
                    std::vector<std::string> names;
                    planner->params().getParamNames(names);
                    std::string known;
                    for (const auto &name : names)
                        known += (known.empty() ? "" : ", ") + name;
                    throw py::value_error("planner " + plannerName + " has no parameter '" + key +
                                          "'; its parameters: " + known);
                }
                const std::string rejected =
                    "planner " + plannerName + " rejected the value '" + value + "' of its parameter '" + key + "'";
                if (litstar && key == "batch_size" && litstar->getPolicyName() != "fixed")
                    throw py::value_error(rejected + ": batch_size is the fixed policy's B, and the '" +
                                          litstar->getPolicyName() + "' policy decides B itself");
                const std::optional<double> given = parseNumber(value);
                // OMPL's setters take any number (AIT* with -3 ran without a word); LIT*'s range for all.
                if (!litstar && key == "rewire_factor" && !(given && *given > 0.0 && *given <= 1e6))
                    throw py::value_error(rejected + ": the rewire factor must be a number in (0, 1e6]");
                // 0: AIT* failed an assertion and aborted the whole process; BIT* and ABIT* ran their budget without
                // a sample.
                if (!litstar && key == "samples_per_batch" && !(given && *given >= 1.0))
                    throw py::value_error(rejected + ": a batch needs at least 1 sample");
                bool accepted = false;
                if (litstar)
                    litstar->noteRefusedParameter("");
                try
                {
                    accepted = planner->params().setParam(key, value);
                }
                catch (const std::exception &error)  // OMPL converts with boost::lexical_cast, which throws
                {
                    throw py::value_error(rejected + ": " + error.what());
                }
                if (!accepted)  // a LIT* setter's reason (OMPL only logs it)
                    throw py::value_error(rejected + (litstar && !litstar->refusedParameter().empty() ?
                                                          ": " + litstar->refusedParameter() :
                                                          std::string()));
                // An unsigned parameter takes "-3" as 4294967293, "1.5" as 1; a setter may clamp: a number must read
                // back as the number given, or the planner would not run with it.
                const std::string stored = planner->params()[key].getValue();
                const std::optional<double> kept = parseNumber(stored);
                if (given && kept && !(std::abs(*kept - *given) <= 1e-9 * std::max(1.0, std::abs(*given))))
                    throw py::value_error(rejected + ": it was stored as " + stored +
                                          ", not the value given (rounded, clamped to the parameter's range, or "
                                          "outside its type's)");
            }
            planner->setProblemDefinition(problem.pdef);

            {
                // Set-up is outside every planner's clock (LIT*'s clock starts in solve as well).
                py::gil_scoped_release release;
                planner->setup();
            }
            const auto startTime = std::chrono::steady_clock::now();
            if (!litstar)
                problem.pdef->setIntermediateSolutionCallback(
                    [&](const ompl::base::Planner *, const std::vector<const ompl::base::State *> &,
                        const ompl::base::Cost cost) {
                        const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - startTime).count();
                        if (improvements.empty() || cost.value() < improvements.back().cost)
                            improvements.push_back({t, cost.value(), problem.checker->calls()});
                    });
            ompl::base::PlannerStatus plannerStatus;
            {
                py::gil_scoped_release release;
                if (litstar)
                    plannerStatus = planner->solve(cancelCondition);
                else if (plannerName != "aitstar")
                    // BIT*, ABIT* and Informed RRT* report each solution through the callback (Informed RRT*
                    // adds its solution to the problem only when solve() ends, which is what a watcher saw);
                    // RRT-Connect stops at its first, which the code below records. (A watcher thread for them
                    // too cost them a share of a core: about 18 % more CPU than wall time, and about 15-16 %
                    // fewer checks within the budget for BIT* and for Informed RRT*, in review helpers'
                    // one-off measurements.)
                    plannerStatus = planner->solve(ompl::base::plannerOrTerminationCondition(
                        ompl::base::timedPlannerTerminationCondition(time), cancelCondition));
                else
                {
                    // OMPL 1.5.2's AIT* does not call the intermediate-solution callback, so a watcher thread
                    // polls the problem definition's solutions every 50 microseconds.
                    std::atomic<bool> done{false};
                    std::mutex mutex;
                    std::vector<Improvement> polled;
                    std::thread watcher([&] {
                        std::size_t seen = 0u;
                        while (!done.load())
                        {
                            const std::size_t count = problem.pdef->getSolutionCount();
                            if (count != seen)
                            {
                                seen = count;
                                const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - startTime).count();
                                const std::uint64_t checks = problem.checker->calls();
                                double c = std::numeric_limits<double>::infinity();
                                for (const auto &solution : problem.pdef->getSolutions())
                                    if (!solution.approximate_)
                                        c = std::min(c, solution.path_->as<ompl::geometric::PathGeometric>()->length());
                                if (std::isfinite(c))
                                {
                                    std::lock_guard<std::mutex> lock(mutex);
                                    polled.push_back({t, c, checks});
                                }
                            }
                            std::this_thread::sleep_for(std::chrono::microseconds(50));
                        }
                    });
                    {
                        // Stops and joins the watcher also when solve() throws (AIT* does, on a start equal to
                        // its goal): a joinable std::thread destroyed on the way out would abort the process.
                        struct StopWatcher
                        {
                            std::atomic<bool> &done;
                            std::thread &watcher;
                            ~StopWatcher()
                            {
                                done.store(true);
                                watcher.join();
                            }
                        } stopWatcher{done, watcher};
                        plannerStatus = planner->solve(ompl::base::plannerOrTerminationCondition(
                            ompl::base::timedPlannerTerminationCondition(time), cancelCondition));
                    }
                    std::lock_guard<std::mutex> lock(mutex);
                    // Merge callback and polled events into one non-increasing cost curve.
                    polled.insert(polled.end(), improvements.begin(), improvements.end());
                    std::sort(polled.begin(), polled.end(), [](const Improvement &a, const Improvement &b) {
                        return std::tie(a.time, a.cost, a.checks) < std::tie(b.time, b.cost, b.checks);
                    });
                    improvements.clear();
                    for (const auto &event : polled)
                        if (improvements.empty() || event.cost < improvements.back().cost - 1e-12)
                            improvements.push_back(event);
                }
            }
            elapsed = litstar ? litstar->planningTime() :
                                std::chrono::duration<double>(std::chrono::steady_clock::now() - startTime).count();
            status = statusName(plannerStatus);
            if (litstar)
            {
                message = litstar->statusMessage();
                for (std::size_t i = 0; i < recorder->solutions.size(); ++i)
                    improvements.push_back(
                        {recorder->solutions[i].time, recorder->solutions[i].cost, recorder->solutionChecks[i]});
            }
        }

        const bool solved = status == "exact_solution" && problem.pdef->hasExactSolution();
        double cost = std::numeric_limits<double>::infinity();
        py::list path;
        if (solved)
        {
            auto solution = problem.pdef->getSolutionPath()->as<ompl::geometric::PathGeometric>();
            cost = solution->length();
            for (std::size_t i = 0; i < solution->getStateCount(); ++i)
            {
                std::vector<double> x;
                problem.si->getStateSpace()->copyToReals(x, solution->getState(i));
                path.append(py::cast(x));
            }
            // Planners that do not report intermediate solutions (RRT-Connect) still have a first solution.
            if (improvements.empty() || cost < improvements.back().cost - 1e-12)
                improvements.push_back({elapsed, cost, problem.checker->calls()});
        }
        py::list improvementList;
        for (const auto &event : improvements)
            improvementList.append(py::make_tuple(event.time, event.cost));

        result["status"] = status;
        result["solved"] = solved;
        result["message"] = message;
        result["cost"] = cost;
        const double infinity = std::numeric_limits<double>::infinity();
        result["t_init"] = improvements.empty() ? infinity : improvements.front().time;
        result["c_init"] = improvements.empty() ? infinity : improvements.front().cost;
        // Validity checks up to the first solution: deterministic for LIT*, unlike t_init. For AIT*, whose solutions
        // are polled (sleep_for's 50 microseconds are a minimum), it can include a polling interval's work or more.
        result["checks_init"] = improvements.empty() ? py::none() : py::cast(improvements.front().checks);
        result["improvements"] = improvementList;
        result["path"] = path;
        result["time"] = elapsed;

        py::dict counters;
        counters["validity_checks"] = problem.checker->calls();
        if (litstar)
        {
            const LITstarCounters &c = litstar->counters();
            counters["iterations"] = c.iterations;
            counters["batches"] = c.batches;
            counters["valid_samples"] = c.validSamples;
            counters["invalid_samples"] = c.invalidSamples;
            counters["pruned_samples"] = c.prunedSamples;
            counters["prunes"] = c.prunes;
            counters["collision_checks"] = c.collisionChecks;
            counters["edges_evaluated"] = c.edgesEvaluated;
            counters["edges_sparsely_checked"] = c.edgesSparselyChecked;
            counters["edges_invalid"] = c.edgesInvalid;
            counters["forward_steps"] = c.forwardSteps;
            counters["reverse_steps"] = c.reverseSteps;
            counters["reverse_restarts"] = c.reverseRestarts;
            counters["expansions"] = c.expansions;
            counters["batch_decisions"] = c.batchDecisions;
            counters["neighbour_decisions"] = c.neighbourDecisions;
            result["policy"] = litstar->getPolicyName();
            // The iteration that found the first solution: max_iterations of a rerun that stops there.
            result["iteration_init"] =
                recorder->solutions.empty() ? py::none() : py::cast(recorder->solutions.front().iteration);
            // The state at the end, per agent: the s' of each agent's last transition in training
            // (the learner's EpisodeEnd). ψ_K's local ratio is taken around the start.
            const Features f = litstar->computeFeatures();
            py::dict finalFeatures;
            finalFeatures["B"] = py::make_tuple(f.rhoGlobal, f.rhoLocalB, f.measure);
            finalFeatures["psi_K"] = py::make_tuple(f.rhoGlobal, f.rhoLocalK, f.measure);
            result["final_features"] = finalFeatures;
        }
        result["counters"] = counters;
        py::list decisions;
        for (const auto &event : recorder->decisions)
            decisions.append(decisionDict(event));
        result["decisions"] = decisions;
        return result;
    }
}  // namespace

PYBIND11_MODULE(lit_core, m)
{
    m.doc() = "LIT* core (C++17 on OMPL 1.5.2): box worlds, the LITstar planner, parameter policies, OMPL baselines";
    py::register_exception<TensorError>(m, "TensorError", PyExc_ValueError);
    py::register_exception_translator([](std::exception_ptr thrown) {
        try
        {
            if (thrown)
                std::rethrow_exception(thrown);
        }
        catch (const PythonPolicyAbort &abort)
        {
            abort.restore();  // the KeyboardInterrupt or SystemExit itself
        }
    });

    m.def("set_log_level", [](const std::string &level) {
        static const std::map<std::string, ompl::msg::LogLevel> levels{{"debug", ompl::msg::LOG_DEBUG},
            {"info", ompl::msg::LOG_INFO}, {"warn", ompl::msg::LOG_WARN}, {"error", ompl::msg::LOG_ERROR},
            {"none", ompl::msg::LOG_NONE}};
        auto it = levels.find(level);
        if (it == levels.end())
            throw py::value_error("log level must be one of debug, info, warn, error, none");
        ompl::msg::setLogLevel(it->second);
    }, py::arg("level"), "Sets OMPL's console log level.");
    m.def("set_global_seed", [](unsigned int seed) { ompl::RNG::setSeed(seed); }, py::arg("seed"),
          "Seeds OMPL's global RNG (OMPL baselines). Effective once per process, before any planner runs.");
    m.def("planner_names", &plannerNames);

    m.def("unit_ball_measure", &unitBallMeasure, py::arg("n"));
    // n = 0 gave 0 (n - 1 wrapped around), a NaN cost the whole space (taken for "no solution").
    m.def(
        "informed_measure",
        [](unsigned int n, double cost, double cmin, double spaceMeasure) {
            if (n == 0u || std::isnan(cost) || !std::isfinite(cmin) || std::isnan(spaceMeasure))
                throw py::value_error("informed_measure needs n >= 1, a cost (inf: none), a finite cmin and a "
                                      "space measure");
            return informedMeasure(n, cost, cmin, spaceMeasure);
        },
        py::arg("n"), py::arg("cost"), py::arg("cmin"), py::arg("space_measure"));
    m.def(
        "measure_feature",
        [](unsigned int n, double informed, double spaceMeasure) {
            if (n == 0u || std::isnan(informed) || std::isnan(spaceMeasure))
                throw py::value_error("measure_feature needs n >= 1 and measures that are numbers");
            return measureFeature(n, informed, spaceMeasure);
        },
        py::arg("n"), py::arg("informed"), py::arg("space_measure"));
    m.def("fit_batch_size", [](double xi, unsigned int n) { return FitPolicy::batchSize(xi, n); }, py::arg("xi"), py::arg("n"),
          "FIT*'s sigmoid-log batch rule (m_min = 1, m_max = 199), unrounded.");

    py::class_<Query>(m, "Query", "A planning query in a box world (axis-aligned, closed box obstacles).")
        .def(py::init([](std::vector<double> lower, std::vector<double> upper, std::vector<std::vector<double>> boxLower,
                         std::vector<std::vector<double>> boxUpper, std::vector<double> start, std::vector<double> goal,
                         double resolution, bool exactEdges) {
                 if (boxLower.size() != boxUpper.size())
                     throw py::value_error("box_lower and box_upper must list the same number of boxes");
                 Query q;
                 q.world.lower = std::move(lower);
                 q.world.upper = std::move(upper);
                 for (std::size_t b = 0; b < boxLower.size(); ++b)
                     q.world.boxes.push_back(Box{boxLower[b], boxUpper[b]});
                 const unsigned int dim = q.world.validatedDimension();
                 if (start.size() != dim || goal.size() != dim)
                     throw py::value_error("start and goal must have dimension " + std::to_string(dim));
                 if (!(resolution > 0.0 && resolution < 1.0))
                     throw py::value_error("resolution must be in (0, 1)");
                 q.start = std::move(start);
                 q.goal = std::move(goal);
                 q.resolution = resolution;
                 q.exactEdges = exactEdges;
                 return q;
             }),
             py::arg("lower"), py::arg("upper"), py::arg("box_lower"), py::arg("box_upper"), py::arg("start"),
             py::arg("goal"), py::arg("resolution"), py::arg("exact_edges") = false)
        .def_property_readonly("dimension", [](const Query &q) { return q.world.lower.size(); })
        .def_readonly("start", &Query::start)
        .def_readonly("goal", &Query::goal)
        .def_readonly("exact_edges", &Query::exactEdges)
        .def_readonly("resolution", &Query::resolution)
        .def("is_valid", [](const Query &q, std::vector<double> x) {
                 if (x.size() != q.world.lower.size())
                     throw py::value_error("point has the wrong dimension");
                 BoxProblem p = makeBoxProblem(q.world, q.start, q.goal, q.resolution);
                 return p.checker->isValidPoint(x.data());
             }, py::arg("x"), "The C++ checker's verdict on one point.");

    py::class_<Features>(m, "Features")
        .def_readonly("rho_global", &Features::rhoGlobal)
        .def_readonly("rho_local_b", &Features::rhoLocalB)
        .def_readonly("rho_local_k", &Features::rhoLocalK)
        .def_readonly("measure", &Features::measure);

    py::class_<DecisionContext>(m, "DecisionContext", "What a policy sees at a decision.")
        .def_property_readonly("kind", [](const DecisionContext &c) { return toString(c.kind); })
        .def_readonly("features", &DecisionContext::features)
        .def_property_readonly("rho_global", [](const DecisionContext &c) { return c.features.rhoGlobal; })
        .def_property_readonly("rho_local", [](const DecisionContext &c) {
            return c.kind == DecisionKind::BatchSize ? c.features.rhoLocalB : c.features.rhoLocalK; })
        .def_property_readonly("measure", [](const DecisionContext &c) { return c.features.measure; })
        .def_readonly("dimension", &DecisionContext::dimension)
        .def_readonly("has_solution", &DecisionContext::hasSolution)
        .def_readonly("cost", &DecisionContext::cost)
        .def_readonly("improvements", &DecisionContext::improvements)
        .def_readonly("path_states", &DecisionContext::pathStates)
        .def_readonly("planning_time", &DecisionContext::planningTime)
        .def_readonly("informed_measure", &DecisionContext::informedMeasure)
        .def_readonly("space_measure", &DecisionContext::spaceMeasure)
        .def_readonly("first_solution_measure", &DecisionContext::firstSolutionMeasure)
        .def_readonly("minimum_cost", &DecisionContext::minimumCost)
        .def_readonly("expansions", &DecisionContext::expansions)
        .def_readonly("batches", &DecisionContext::batches)
        .def_readonly("checks", &DecisionContext::checks,
                      "States LIT* has checked so far (samples and edge points).");

    py::class_<SolutionEvent>(m, "SolutionEvent")
        .def_readonly("time", &SolutionEvent::time)
        .def_readonly("cost", &SolutionEvent::cost)
        .def_readonly("path_states", &SolutionEvent::pathStates)
        .def_readonly("improvement", &SolutionEvent::improvement)
        .def_readonly("iteration", &SolutionEvent::iteration);
    py::class_<DecisionEvent>(m, "DecisionEvent")
        .def_property_readonly("kind", [](const DecisionEvent &e) { return toString(e.kind); })
        .def_readonly("features", &DecisionEvent::features)
        .def_readonly("value", &DecisionEvent::value)
        .def_readonly("neighbours", &DecisionEvent::neighbours)
        .def_readonly("policy", &DecisionEvent::policy)
        .def_readonly("time", &DecisionEvent::time)
        .def_readonly("iteration", &DecisionEvent::iteration);
    py::class_<BatchEvent>(m, "BatchEvent")
        .def_readonly("batch", &BatchEvent::batch)
        .def_readonly("batch_size", &BatchEvent::batchSize)
        .def_readonly("valid_samples", &BatchEvent::validSamples)
        .def_readonly("invalid_samples", &BatchEvent::invalidSamples)
        .def_readonly("pruned_samples", &BatchEvent::prunedSamples)
        .def_readonly("time", &BatchEvent::time);

    py::enum_<Interpolation>(m, "Interpolation")
        .value("nearest", Interpolation::Nearest)
        .value("trilinear", Interpolation::Trilinear);

    py::class_<LookupTensor, std::shared_ptr<LookupTensor>>(m, "LookupTensor", "A validated 3-D lookup tensor.")
        .def_static("load", [](const std::string &path, std::array<std::size_t, 3> shape, double minValue, double maxValue) {
                return std::make_shared<LookupTensor>(LookupTensor::load(path, TensorSpec{shape, minValue, maxValue}));
            }, py::arg("path"), py::arg("shape"), py::arg("min_value"), py::arg("max_value"),
            "Loads an NPY v1.0 '<f4' tensor and checks it against the sidecar's shape and range; raises TensorError.")
        // From Python a non-finite feature is an error, as in lit_planner.tensor_files.lookup (the planner's own
        // features are always finite; the C++ lookup maps a non-finite one to 0).
        .def("nearest", [](const LookupTensor &tensor, double x, double y, double z) {
                 checkFeatures(x, y, z);
                 return tensor.nearest(x, y, z);
             }, py::arg("x"), py::arg("y"), py::arg("z"))
        .def("trilinear", [](const LookupTensor &tensor, double x, double y, double z) {
                 checkFeatures(x, y, z);
                 return tensor.trilinear(x, y, z);
             }, py::arg("x"), py::arg("y"), py::arg("z"))
        .def(
            "at",
            [](const LookupTensor &tensor, std::size_t i, std::size_t j, std::size_t k) {
                const auto &shape = tensor.shape();
                if (i >= shape[0] || j >= shape[1] || k >= shape[2])
                    throw py::index_error("grid index (" + std::to_string(i) + ", " + std::to_string(j) + ", " +
                                          std::to_string(k) + ") is outside the shape (" + std::to_string(shape[0]) +
                                          ", " + std::to_string(shape[1]) + ", " + std::to_string(shape[2]) + ")");
                return tensor.at(i, j, k);
            },
            py::arg("i"), py::arg("j"), py::arg("k"), "The value at grid indices i, j, k (IndexError outside).")
        .def_property_readonly("shape", &LookupTensor::shape);

    py::class_<TskActor>(m, "TskActor",
                         "The learner's actor for one state, compiled (lit_learner.networks.ActorSnapshot uses it).")
        .def(py::init<std::array<double, 3>, double, TskActor::Layer, std::vector<TskActor::Layer>, Eigen::VectorXd>(),
             py::arg("centres"), py::arg("sigma"), py::arg("trunk"), py::arg("layers"), py::arg("consequents"),
             "trunk and layers are (weight, bias) pairs; raises ValueError when shapes do not chain.")
        .def("__call__", &TskActor::operator(), py::arg("rho_global"), py::arg("rho_local"), py::arg("measure"));

    py::class_<ParameterPolicy, std::shared_ptr<ParameterPolicy>>(m, "ParameterPolicy")
        .def_property_readonly("name", &ParameterPolicy::name);
    py::class_<FixedPolicy, ParameterPolicy, std::shared_ptr<FixedPolicy>>(m, "FixedPolicy")
        .def(py::init<int, double>(), py::arg("batch_size") = 100, py::arg("neighbour_factor") = M_E);
    py::class_<FitPolicy, ParameterPolicy, std::shared_ptr<FitPolicy>>(m, "FitPolicy").def(py::init<>());
    py::class_<TensorPolicy, ParameterPolicy, std::shared_ptr<TensorPolicy>>(m, "TensorPolicy")
        .def(py::init<std::shared_ptr<const LookupTensor>, std::shared_ptr<const LookupTensor>, Interpolation,
                      unsigned int>(),
             py::arg("batch_tensor"), py::arg("neighbour_tensor"), py::arg("interpolation") = Interpolation::Trilinear,
             py::arg("decision_interval") = 0u,
             "decision_interval: the expansions per psi_K decision the psi_K tensor was trained with (0: not known)")
        .def_property_readonly("decision_interval", &TensorPolicy::decisionInterval)
        .def_property_readonly("interpolation", &TensorPolicy::interpolation);
    py::class_<ExternalPolicy, ParameterPolicy, std::shared_ptr<ExternalPolicy>>(m, "ExternalPolicy")
        .def(py::init([](py::function callback, bool decidesNeighbourFactor) {
                 auto holder = std::make_shared<py::function>(std::move(callback));
                 ExternalPolicy::Callback call = [holder](const DecisionContext &context) {
                     py::gil_scoped_acquire gil;
                     py::object answer;
                     try
                     {
                         answer = (*holder)(context);
                     }
                     catch (py::error_already_set &error)
                     {
                         if (!error.matches(PyExc_Exception))  // KeyboardInterrupt, SystemExit: not a failed answer
                             throw PythonPolicyAbort(std::move(error));
                         throw;
                     }
                     // Converted here, not with cast<double>(), which clears the error: a KeyboardInterrupt raised
                     // while the answer converts (its __float__) or is shown (its __repr__) was counted as one failed
                     // answer, and the plan went on.
                     const auto abortOnInterrupt = [] {
                         py::error_already_set error;
                         if (!error.matches(PyExc_Exception))
                             throw PythonPolicyAbort(std::move(error));
                     };
                     const double value = PyFloat_AsDouble(answer.ptr());
                     if (!(value == -1.0 && PyErr_Occurred()))
                         return value;
                     abortOnInterrupt();  // else the error is dropped: an answer that is no number is a failure
                     // An int beyond a double's range (10**400) does not convert either.
                     std::string shown;
                     try
                     {
                         shown = py::repr(answer);
                     }
                     catch (py::error_already_set &error)
                     {
                         if (!error.matches(PyExc_Exception))
                             throw PythonPolicyAbort(std::move(error));
                         shown = "an object of type " + std::string(Py_TYPE(answer.ptr())->tp_name);
                     }
                     if (shown.size() > 60u)
                         shown = shown.substr(0, 57u) + "...";
                     throw std::runtime_error("external policy answered " + shown + " for " + toString(context.kind) +
                                              ", expected a number a double can hold");
                 };
                 // The py::function must be released with the GIL held.
                 return std::make_shared<ExternalPolicy>(std::move(call), decidesNeighbourFactor);
             }),
             py::arg("callback"), py::arg("decides_neighbour_factor") = true,
             "callback(context: DecisionContext) -> float is asked for B and psi_K; the planner's clock is paused meanwhile.")
        .def_property_readonly("failures", &ExternalPolicy::failures);

    py::class_<CancelFlag>(m, "CancelFlag",
                           "Passed to solve(cancel=...); set() from another thread ends that solve early.")
        .def(py::init<>())
        .def("set", [](CancelFlag &self) { self.flag->store(true); })
        .def("is_set", [](const CancelFlag &self) { return self.flag->load(); });

    m.def("solve", &solveQuery, py::arg("query"), py::arg("planner"), py::arg("time") = 0.0,
          py::arg("policy") = nullptr, py::arg("seed") = 1u, py::arg("max_iterations") = 0u,
          py::arg("max_batches") = 0u, py::arg("params") = std::map<std::string, std::string>{},
          py::arg("listener") = py::none(), py::arg("cancel") = nullptr, py::kw_only(), py::arg("features") = true,
          "Plans \e query with \e planner. LIT* stops on its own clock (time), iterations or batches; OMPL planners on "
          "wall time. Returns a dict: status, solved, message, cost, t_init, c_init, "
          "checks_init (validity checks up to the first solution, None without one), improvements, path, time, "
          "counters, decisions; for LIT* also policy, iteration_init (the iteration of the first solution, None "
          "without one) and final_features. features=False: a policy that needs no features (fixed, fit) is not "
          "given the path feature rho_local_b either (a scan around the path at every improvement, with the clock "
          "paused); its B decisions report NaN for it.");
}
