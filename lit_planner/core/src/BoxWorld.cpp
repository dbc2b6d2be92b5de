#include "lit/BoxWorld.h"

#include <ompl/base/ProblemDefinition.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

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
        // Each box as the axes on which it does not cover the bounds, narrowest cover first: a point inside the
        // bounds is inside the box on every other axis, and the narrowest cover is the one a point most likely
        // misses, so the test leaves early. A box that misses the bounds on an axis holds no point inside them.
        // (The order of the axes and the boxes cannot change what the test answers.)
        boxLower_.reserve(world.boxes.size() * dim_);
        boxUpper_.reserve(world.boxes.size() * dim_);
        for (const auto &box : world.boxes)
        {
            boxLower_.insert(boxLower_.end(), box.lower.begin(), box.lower.end());
            boxUpper_.insert(boxUpper_.end(), box.upper.begin(), box.upper.end());
        }
        boxBegin_.push_back(0u);
        for (const auto &box : world.boxes)
        {
            std::vector<std::pair<double, Interval>> axes;
            bool missesBounds = false;
            for (unsigned int i = 0; i < dim_; ++i)
            {
                if (box.lower[i] > upper_[i] || box.upper[i] < lower_[i])
                    missesBounds = true;
                if (box.lower[i] <= lower_[i] && box.upper[i] >= upper_[i])
                    continue;  // covers the bounds on this axis
                const double cover = (std::min(box.upper[i], upper_[i]) - std::max(box.lower[i], lower_[i])) /
                                     (upper_[i] - lower_[i]);
                // (NaN only for bounds whose extent overflows: last, so that the sort's order stays strict.)
                axes.emplace_back(std::isnan(cover) ? 2.0 : cover, Interval{box.lower[i], box.upper[i], i});
            }
            if (missesBounds)
                continue;
            std::stable_sort(axes.begin(), axes.end(),
                             [](const auto &a, const auto &b) { return a.first < b.first; });
            for (const auto &axis : axes)
                intervals_.push_back(axis.second);
            boxBegin_.push_back(intervals_.size());
        }
        // The grid: per axis, GRID_CELLS cells, each with the bit set of the boxes whose interval on that axis
        // meets the cell widened by two cells on either side. A point's cell (as computed, within one cell of its
        // true one) then has every box that holds the point, with a margin of a cell for the rounding.
        const std::size_t boxes = boxBegin_.size() - 1u;
        maskWords_ = (boxes + 63u) / 64u;
        cellScale_.resize(dim_);
        for (unsigned int i = 0; i < dim_; ++i)
            cellScale_[i] = static_cast<double>(GRID_CELLS) / (upper_[i] - lower_[i]);
        useGrid_ = boxes >= 4u && std::all_of(cellScale_.begin(), cellScale_.end(),
                                              [](double scale) { return std::isfinite(scale) && scale > 0.0; });
        if (useGrid_)
        {
            cellMasks_.assign(static_cast<std::size_t>(dim_) * GRID_CELLS * maskWords_, 0u);
            for (unsigned int i = 0; i < dim_; ++i)
            {
                const double width = (upper_[i] - lower_[i]) / static_cast<double>(GRID_CELLS);
                for (unsigned int c = 0; c < GRID_CELLS; ++c)
                {
                    const double from = lower_[i] + (static_cast<double>(c) - 2.0) * width;
                    const double to = lower_[i] + (static_cast<double>(c) + 3.0) * width;
                    std::uint64_t *mask = &cellMasks_[(static_cast<std::size_t>(i) * GRID_CELLS + c) * maskWords_];
                    for (std::size_t b = 0; b < boxes; ++b)
                    {
                        bool meets = true;  // a box that covers the axis has no interval on it
                        for (std::size_t k = boxBegin_[b]; k < boxBegin_[b + 1u]; ++k)
                            if (intervals_[k].axis == i)
                                meets = intervals_[k].lower <= to && intervals_[k].upper >= from;
                        if (meets)
                            mask[b / 64u] |= std::uint64_t{1} << (b % 64u);
                    }
                }
            }
        }
    }

    bool BoxWorldValidityChecker::insideBox(const double *x, std::size_t box) const
    {
        const Interval *interval = intervals_.data() + boxBegin_[box];
        const Interval *end = intervals_.data() + boxBegin_[box + 1u];
        while (interval != end && x[interval->axis] >= interval->lower && x[interval->axis] <= interval->upper)
            ++interval;
        return interval == end;
    }

    bool BoxWorldValidityChecker::isValidPoint(const double *x) const
    {
        for (unsigned int i = 0; i < dim_; ++i)
            if (!(x[i] >= lower_[i] && x[i] <= upper_[i]))  // also rejects NaN
                return false;
        if (!useGrid_)
        {
            // Few boxes: each one axis by axis (as fast as the grid's lookups, or faster).
            const std::size_t numBoxes = boxLower_.size() / dim_;  // dim_ >= 1 (validatedDimension)
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
        // The boxes in the point's cell on every axis, each then tested (x is inside the bounds: (x - lower) * scale
        // is in [0, GRID_CELLS], and the last cell also takes the upper bound).
        for (std::size_t w = 0; w < maskWords_; ++w)
        {
            std::uint64_t candidates = ~std::uint64_t{0};
            for (unsigned int i = 0; i < dim_ && candidates != 0u; ++i)
            {
                const double t = (x[i] - lower_[i]) * cellScale_[i];
                const std::size_t cell = t < static_cast<double>(GRID_CELLS) ? static_cast<std::size_t>(t)
                                                                              : GRID_CELLS - 1u;
                candidates &= cellMasks_[(static_cast<std::size_t>(i) * GRID_CELLS + cell) * maskWords_ + w];
            }
            while (candidates != 0u)
            {
                const unsigned int bit = static_cast<unsigned int>(__builtin_ctzll(candidates));
                candidates &= candidates - 1u;
                if (insideBox(x, w * 64u + bit))
                    return false;
            }
        }
        return true;
    }

    bool BoxWorldValidityChecker::isValid(const ompl::base::State *state) const
    {
        return isValidCounted(state->as<ompl::base::RealVectorStateSpace::StateType>()->values);
    }

    BoxWorldMotionValidator::BoxWorldMotionValidator(const ompl::base::SpaceInformationPtr &si,
                                                     const BoxWorld &world)
      : ompl::base::MotionValidator(si), dim_(world.validatedDimension())
    {
        for (const auto &box : world.boxes)
        {
            boxLower_.insert(boxLower_.end(), box.lower.begin(), box.lower.end());
            boxUpper_.insert(boxUpper_.end(), box.upper.begin(), box.upper.end());
        }
    }

    double BoxWorldMotionValidator::firstContact(const double *a, const double *b) const
    {
        double first = std::numeric_limits<double>::infinity();
        const std::size_t numBoxes = boxLower_.size() / (dim_ == 0u ? 1u : dim_);
        for (std::size_t k = 0; k < numBoxes; ++k)
        {
            const double *lo = &boxLower_[k * dim_];
            const double *hi = &boxUpper_[k * dim_];
            double enter = 0.0, leave = 1.0;  // the part of the segment inside every slab so far
            unsigned int i = 0;
            for (; i < dim_; ++i)
            {
                const double d = b[i] - a[i];
                if (d == 0.0)
                {
                    if (a[i] < lo[i] || a[i] > hi[i])
                        break;
                    continue;
                }
                double t0 = (lo[i] - a[i]) / d, t1 = (hi[i] - a[i]) / d;
                if (t0 > t1)
                    std::swap(t0, t1);
                enter = std::max(enter, t0);
                leave = std::min(leave, t1);
                if (enter > leave)  // closed boxes: touching a face (enter == leave) is a contact
                    break;
            }
            if (i == dim_)
                first = std::min(first, enter);
        }
        return first;
    }

    bool BoxWorldMotionValidator::checkMotion(const ompl::base::State *s1, const ompl::base::State *s2) const
    {
        const bool valid = si_->isValid(s2) &&
                           !std::isfinite(firstContact(s1->as<ompl::base::RealVectorStateSpace::StateType>()->values,
                                                       s2->as<ompl::base::RealVectorStateSpace::StateType>()->values));
        if (valid)
            ++valid_;
        else
            ++invalid_;
        return valid;
    }

    bool BoxWorldMotionValidator::checkMotion(const ompl::base::State *s1, const ompl::base::State *s2,
                                              std::pair<ompl::base::State *, double> &lastValid) const
    {
        const double contact = firstContact(s1->as<ompl::base::RealVectorStateSpace::StateType>()->values,
                                            s2->as<ompl::base::RealVectorStateSpace::StateType>()->values);
        if (!std::isfinite(contact) && si_->isValid(s2))
        {
            ++valid_;
            return true;
        }
        ++invalid_;
        // A valid state before the first contact (a box, or the bounds the end state is outside of): just before
        // it, then halfway back towards s1 while rounding leaves it on a face or outside (at most 64 times);
        // s1 itself (t = 0) when none is.
        double t = std::isfinite(contact) ? std::max(0.0, contact - 1e-9) : 1.0 - 1e-9;
        ompl::base::State *probe = lastValid.first != nullptr ? lastValid.first : si_->allocState();
        int halvings = 0;
        for (; t > 0.0 && halvings < 64; t *= 0.5, ++halvings)
        {
            si_->getStateSpace()->interpolate(s1, s2, t, probe);
            if (si_->isValid(probe) &&
                !std::isfinite(firstContact(s1->as<ompl::base::RealVectorStateSpace::StateType>()->values,
                                            probe->as<ompl::base::RealVectorStateSpace::StateType>()->values)))
                break;
        }
        if (!(t > 0.0) || halvings == 64)
        {
            t = 0.0;
            si_->copyState(probe, s1);
        }
        if (lastValid.first == nullptr)
            si_->freeState(probe);
        lastValid.second = t;
        return false;
    }

    BoxProblem makeBoxProblem(const BoxWorld &world, const std::vector<double> &start,
                              const std::vector<double> &goal, double resolution, bool exactEdges)
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
        if (exactEdges)
            problem.si->setMotionValidator(std::make_shared<BoxWorldMotionValidator>(problem.si, world));
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
