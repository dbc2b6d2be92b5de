#include "lit/BoxWorld.h"

#include <ompl/base/ProblemDefinition.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace lit
{
    unsigned int BoxWorld::validatedDimension() const
    {
        if (lower.empty() || lower.size() != upper.size())
            throw std::invalid_argument("world bounds: lower and upper must be non-empty and of equal length");
        for (std::size_t i = 0; i < lower.size(); ++i)
            if (!(std::isfinite(lower[i]) && std::isfinite(upper[i]) && lower[i] < upper[i]))
                throw std::invalid_argument("world bounds: axis " + std::to_string(i) +
                                            " needs finite lower < upper");
        for (std::size_t b = 0; b < boxes.size(); ++b)
        {
            if (boxes[b].lower.size() != lower.size() || boxes[b].upper.size() != lower.size())
                throw std::invalid_argument("box " + std::to_string(b) + ": corner dimension differs from the world's");
            for (std::size_t i = 0; i < lower.size(); ++i)
                if (!(std::isfinite(boxes[b].lower[i]) && std::isfinite(boxes[b].upper[i]) &&
                      boxes[b].lower[i] <= boxes[b].upper[i]))
                    throw std::invalid_argument("box " + std::to_string(b) + ": axis " + std::to_string(i) +
                                                " needs finite lower <= upper");
        }
        return static_cast<unsigned int>(lower.size());
    }

    BoxWorldValidityChecker::BoxWorldValidityChecker(const ompl::base::SpaceInformationPtr &si,
                                                     const BoxWorld &world)
      : ompl::base::StateValidityChecker(si)
      , dim_(world.validatedDimension())
      , lower_(world.lower)
      , upper_(world.upper)
    {
        boxLower_.reserve(world.boxes.size() * dim_);
        boxUpper_.reserve(world.boxes.size() * dim_);
        for (const auto &box : world.boxes)
        {
            boxLower_.insert(boxLower_.end(), box.lower.begin(), box.lower.end());
            boxUpper_.insert(boxUpper_.end(), box.upper.begin(), box.upper.end());
        }
    }

    bool BoxWorldValidityChecker::isValidPoint(const double *x) const
    {
        for (unsigned int i = 0; i < dim_; ++i)
            if (!(x[i] >= lower_[i] && x[i] <= upper_[i]))  // also rejects NaN
                return false;
        const std::size_t numBoxes = boxLower_.size() / (dim_ == 0u ? 1u : dim_);
        for (std::size_t b = 0; b < numBoxes; ++b)
        {
            const double *lo = &boxLower_[b * dim_];
            const double *hi = &boxUpper_[b * dim_];
            unsigned int i = 0;
            while (i < dim_ && x[i] >= lo[i] && x[i] <= hi[i])
                ++i;
            if (i == dim_)
                return false;
        }
        return true;
    }

    bool BoxWorldValidityChecker::isValid(const ompl::base::State *state) const
    {
        calls_.fetch_add(1u, std::memory_order_relaxed);
        return isValidPoint(state->as<ompl::base::RealVectorStateSpace::StateType>()->values);
    }

    BoxProblem makeBoxProblem(const BoxWorld &world, const std::vector<double> &start,
                              const std::vector<double> &goal, double resolution)
    {
        const unsigned int dim = world.validatedDimension();
        if (start.size() != dim || goal.size() != dim)
            throw std::invalid_argument("start and goal must have the world's dimension " + std::to_string(dim));
        if (!(resolution > 0.0 && resolution < 1.0))
            throw std::invalid_argument("resolution must be in (0, 1)");

        auto space = std::make_shared<ompl::base::RealVectorStateSpace>(dim);
        ompl::base::RealVectorBounds bounds(dim);
        for (unsigned int i = 0; i < dim; ++i)
        {
            bounds.setLow(i, world.lower[i]);
            bounds.setHigh(i, world.upper[i]);
        }
        space->setBounds(bounds);

        BoxProblem problem;
        problem.world = world;
        problem.si = std::make_shared<ompl::base::SpaceInformation>(space);
        problem.checker = std::make_shared<BoxWorldValidityChecker>(problem.si, world);
        problem.si->setStateValidityChecker(problem.checker);
        problem.si->setStateValidityCheckingResolution(resolution);
        problem.si->setup();

        problem.pdef = std::make_shared<ompl::base::ProblemDefinition>(problem.si);
        ompl::base::ScopedState<> startState(space), goalState(space);
        for (unsigned int i = 0; i < dim; ++i)
        {
            startState[i] = start[i];
            goalState[i] = goal[i];
        }
        problem.pdef->addStartState(startState);
        problem.pdef->setGoalState(goalState);
        problem.pdef->setOptimizationObjective(
            std::make_shared<ompl::base::PathLengthOptimizationObjective>(problem.si));
        return problem;
    }
}  // namespace lit
