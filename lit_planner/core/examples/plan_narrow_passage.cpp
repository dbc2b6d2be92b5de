// LIT* in an OMPL program of one's own: the narrow passage in R^8 (a wall across x0 in [-0.1, 0.1]
// with a free slab 0.05 < x1 < 0.15; the same problem as `./lit plan --scenario np8`), a validity checker
// written here, OMPL's SimpleSetup, and LIT* with the trained lookup tensors (or FIT*'s rule when
// no tensor folder is given).
//
//   plan_narrow_passage [TENSOR_DIR [SECONDS [SEED [DECISION_INTERVAL]]]]
//
// TENSOR_DIR must hold both tensors, b_tensor.npy and k_tensor.npy (this program loads both; the
// library's lit::TensorPolicy, like `lit plan`, also takes one alone and keeps the other parameter at
// its fixed value); an empty TENSOR_DIR ("") plans with FIT*'s rule.
// DECISION_INTERVAL: expansions per psi_K decision, default 10, the interval the shipped tensors were
// trained with. Give your tensors' own: k_tensor.json's provenance.decision_interval, which the Python
// side applies by itself (1 where it names none).
//
// Prints the status, the time to the first solution, its cost and the final cost; exits 0 when the
// problem was solved.
#include <lit/LITstar.h>
#include <lit/LookupTensor.h>
#include <lit/ParameterPolicy.h>
#include <lit/PlannerListener.h>

#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/geometric/SimpleSetup.h>
#include <ompl/util/Console.h>

#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <stdexcept>
#include <memory>
#include <string>
#include <utility>

namespace ob = ompl::base;
namespace og = ompl::geometric;

namespace
{
    constexpr unsigned int dimension = 8;

    // The first solution's planner time and cost, as LIT* reports them.
    class FirstSolution : public lit::PlannerListener
    {
    public:
        void onSolution(const lit::SolutionEvent &event) override
        {
            if (event.improvement == 1u)
            {
                time = event.time;
                cost = event.cost;
                iteration = event.iteration;
            }
        }
        double time{-1.0};
        double cost{-1.0};
        std::size_t iteration{0u};
    };

    // The tensor policy from a folder that `lit train --export` wrote (both tensors). The grid and the
    // value ranges given here are those of LIT*'s tensors, as their sidecars (b_tensor.json,
    // k_tensor.json) state them; the loader checks each file against these (it does not read the
    // sidecars, which the Python side validates) and throws lit::TensorError on any mismatch.
    lit::ParameterPolicyPtr tensorPolicy(const std::string &folder)
    {
        const auto load = [&folder](const char *file, double low, double high) {
            return std::make_shared<const lit::LookupTensor>(
                lit::LookupTensor::load(folder + "/" + file, lit::TensorSpec{{{101u, 101u, 101u}}, low, high}));
        };
        // In this order (the order of a call's arguments is unspecified): a folder without tensors is named by
        // its first file, b_tensor.npy.
        auto batchSize = load("b_tensor.npy", 20.0, 200.0);
        auto neighbourFactor = load("k_tensor.npy", 3.0, 15.0);
        return std::make_shared<lit::TensorPolicy>(std::move(batchSize), std::move(neighbourFactor),
                                                   lit::Interpolation::Trilinear);
    }

    // The whole of an argument as a number, or an error naming it (std::stod alone says "stod").
    double numberArgument(const std::string &text, const std::string &name)
    {
        std::size_t used = 0u;
        double value = 0.0;
        try
        {
            value = std::stod(text, &used);
        }
        catch (const std::exception &)
        {
            used = 0u;
        }
        if (used == 0u || used != text.size() || !std::isfinite(value))
            throw std::invalid_argument(name + " must be a number, got '" + text + "'");
        return value;
    }

    long long wholeArgument(const std::string &text, const std::string &name)
    {
        const double value = numberArgument(text, name);
        if (value != std::floor(value) || std::fabs(value) > 9.0e15)
            throw std::invalid_argument(name + " must be a whole number, got '" + text + "'");
        return static_cast<long long>(value);
    }
}  // namespace

int main(int argc, char **argv)
{
    try
    {
        const std::string tensors = argc > 1 ? argv[1] : "";
        const double seconds = argc > 2 ? numberArgument(argv[2], "SECONDS") : 0.4;
        const long long seed = argc > 3 ? wholeArgument(argv[3], "SEED") : 1;
        const long long interval = argc > 4 ? wholeArgument(argv[4], "DECISION_INTERVAL") : 10;
        // OMPL's time-based stop counts nanoseconds in 64 bits: from about 9.2e9 s on it stops at once.
        if (!(seconds > 0.0 && seconds <= 1e9))
            throw std::invalid_argument("SECONDS must be positive and at most 1e9, got " + std::string(argv[2]));
        if (seed < 0 || seed > std::numeric_limits<unsigned int>::max())
            throw std::invalid_argument("the seed must be between 0 and " +
                                        std::to_string(std::numeric_limits<unsigned int>::max()));
        if (interval < 1 || interval > 10000)
            throw std::invalid_argument("the decision interval must be between 1 and 10000");
        ompl::msg::setLogLevel(ompl::msg::LOG_WARN);

        auto space = std::make_shared<ob::RealVectorStateSpace>(dimension);
        space->setBounds(-0.5, 0.5);
        og::SimpleSetup setup(space);
        setup.setStateValidityChecker([](const ob::State *state) {
            const double *x = state->as<ob::RealVectorStateSpace::StateType>()->values;
            const bool inWall = x[0] >= -0.1 && x[0] <= 0.1;
            const bool inGap = x[1] > 0.05 && x[1] < 0.15;
            return !inWall || inGap;
        });
        // Edges are checked every 5e-6 of the space's largest extent (PDT's default).
        setup.getSpaceInformation()->setStateValidityCheckingResolution(5e-6);
        ob::ScopedState<> start(space), goal(space);
        for (unsigned int i = 0; i < dimension; ++i)
            start[i] = goal[i] = 0.0;
        start[0] = -0.2;
        goal[0] = 0.2;
        setup.setStartAndGoalStates(start, goal);
        setup.setOptimizationObjective(
            std::make_shared<ob::PathLengthOptimizationObjective>(setup.getSpaceInformation()));

        auto planner = std::make_shared<lit::LITstar>(setup.getSpaceInformation());
        if (tensors.empty())
            planner->setPolicyName("fit");
        else
            planner->setPolicy(tensorPolicy(tensors));
        planner->setDecisionInterval(static_cast<unsigned int>(interval));
        planner->setSeed(static_cast<unsigned int>(seed));
        auto first = std::make_shared<FirstSolution>();
        planner->addListener(first);
        setup.setPlanner(planner);

        const ob::PlannerStatus status = setup.solve(seconds);
        const bool solved = status == ob::PlannerStatus::EXACT_SOLUTION;
        std::printf("policy %s, %u-D narrow passage, %.3g s, seed %lld: %s\n", planner->getPolicy()->name().c_str(),
                    dimension, seconds, seed, status.asString().c_str());
        if (solved)
            std::printf("first solution after %.2f ms (iteration %zu), cost %.4f; final cost %.4f (optimum 0.4236); "
                        "%zu batches, %zu collision checks\n",
                        first->time * 1e3, first->iteration, first->cost, planner->bestCost(),
                        planner->counters().batches, planner->counters().collisionChecks);
        return solved ? 0 : 1;
    }
    catch (const std::exception &error)
    {
        std::fprintf(stderr, "plan_narrow_passage: %s\n", error.what());
        return 2;
    }
}
