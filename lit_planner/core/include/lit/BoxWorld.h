#pragma once
/** \file BoxWorld.h
 *  \brief Hyperrectangle worlds in R^n and a validity checker that counts its calls. */

#include <ompl/base/MotionValidator.h>
#include <ompl/base/SpaceInformation.h>
#include <ompl/base/ProblemDefinition.h>
#include <ompl/base/StateValidityChecker.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

namespace lit
{
    /** \brief An axis-aligned, closed box obstacle: a point collides iff lower <= x <= upper on every axis. */
    struct Box
    {
        std::vector<double> lower;
        std::vector<double> upper;
    };

    /** \brief A world: the space bounds and the obstacles. */
    struct BoxWorld
    {
        /** \brief Lower corner of the state space. */
        std::vector<double> lower;
        /** \brief Upper corner of the state space. */
        std::vector<double> upper;
        /** \brief The obstacles. */
        std::vector<Box> boxes;

        /** \brief Dimension of the world; throws std::invalid_argument if the description is inconsistent. */
        unsigned int validatedDimension() const;
    };

    /** \brief Validity checker for a BoxWorld. Counts every call (thread-safe, relaxed). */
    class BoxWorldValidityChecker : public ompl::base::StateValidityChecker
    {
    public:
        /** \brief Checker for \e world on \e si (an R^n space of the world's dimension). */
        BoxWorldValidityChecker(const ompl::base::SpaceInformationPtr &si, const BoxWorld &world);

        /** \brief True iff the state lies inside the bounds and outside every box. */
        bool isValid(const ompl::base::State *state) const override;

        /** \brief The same test on raw coordinates, without counting. */
        bool isValidPoint(const double *x) const;

        /** \brief isValid() on raw coordinates: the same test, counted as a call. */
        bool isValidCounted(const double *x) const
        {
            calls_.fetch_add(1u, std::memory_order_relaxed);
            return isValidPoint(x);
        }

        /** \brief Number of isValid calls since construction or the last reset. */
        std::uint64_t calls() const
        {
            return calls_.load(std::memory_order_relaxed);
        }

        /** \brief Sets the call counter to zero. */
        void resetCalls()
        {
            calls_.store(0, std::memory_order_relaxed);
        }

    private:
        /** \brief Dimension. */
        unsigned int dim_{0u};
        /** \brief Bounds, flattened. */
        std::vector<double> lower_, upper_;
        /** \brief Box corners, flattened box-major: boxLower_[b * dim_ + i] (the test without the grid). */
        std::vector<double> boxLower_, boxUpper_;
        /** \brief A box's extent on one axis. */
        struct Interval
        {
            double lower;
            double upper;
            unsigned int axis;
        };
        /** \brief The boxes that meet the bounds, each as its intervals on the axes where it does not cover them
         *  (narrowest first): box b's are intervals_[boxBegin_[b], boxBegin_[b + 1]). */
        std::vector<Interval> intervals_;
        std::vector<std::size_t> boxBegin_;
        /** \brief Whether \e x (inside the bounds) is inside box \e box (of those kept). */
        bool insideBox(const double *x, std::size_t box) const;
        /** \brief A grid over the bounds that narrows the boxes to test: cellMasks_[(axis * GRID_CELLS + cell) *
         *  maskWords_ + w] holds bits w * 64 ... of the boxes that may hold a point of that cell on that axis. */
        static constexpr unsigned int GRID_CELLS = 64u;
        bool useGrid_{false};
        std::size_t maskWords_{0u};
        std::vector<double> cellScale_;
        std::vector<std::uint64_t> cellMasks_;
        /** \brief Call counter. */
        mutable std::atomic<std::uint64_t> calls_{0u};
    };

    /** \brief Everything a planning query on a BoxWorld needs: space, checker, problem definition. */
    struct BoxProblem
    {
        ompl::base::SpaceInformationPtr si;
        ompl::base::ProblemDefinitionPtr pdef;
        std::shared_ptr<BoxWorldValidityChecker> checker;
        BoxWorld world;
    };

    /** \brief Exact motion validation in a BoxWorld: a straight segment is valid iff its end state is valid and
     *  it meets no (closed) box, by a slab test per box, however thin the box or short the clip of its corner.
     *  The discrete check at a resolution can step over both (a path the exact re-check then refuses). */
    class BoxWorldMotionValidator : public ompl::base::MotionValidator
    {
    public:
        BoxWorldMotionValidator(const ompl::base::SpaceInformationPtr &si, const BoxWorld &world);

        /** \brief As OMPL's validators: \e s1 is taken as valid. */
        bool checkMotion(const ompl::base::State *s1, const ompl::base::State *s2) const override;

        /** \brief Also gives the last valid state and its fraction of the segment (just before the first box). */
        bool checkMotion(const ompl::base::State *s1, const ompl::base::State *s2,
                         std::pair<ompl::base::State *, double> &lastValid) const override;

        /** \brief The fraction t in [0, 1] where the segment a -> b first meets a box; infinity when it meets none. */
        double firstContact(const double *a, const double *b) const;

    private:
        unsigned int dim_{0u};
        std::vector<double> boxLower_, boxUpper_;
    };

    /** \brief Builds an R^n problem with path-length objective. \e resolution is OMPL's
     *  state-validity-checking resolution (a fraction of the space's maximum extent). With \e exactEdges the
     *  motion validator is BoxWorldMotionValidator (custom worlds), else OMPL's discrete one at the resolution
     *  (the benchmark scenarios: the same checks for every planner, as PDT's). Start and goal are not validated
     *  here: the planners report invalid ones with a status. */
    BoxProblem makeBoxProblem(const BoxWorld &world, const std::vector<double> &start,
                              const std::vector<double> &goal, double resolution, bool exactEdges = false);
}  // namespace lit
