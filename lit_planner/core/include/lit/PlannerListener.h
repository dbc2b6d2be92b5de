#pragma once
/** \file PlannerListener.h
 *  \brief What LIT* reports while it plans: solution improvements, decisions, batches. */

#include "lit/ParameterPolicy.h"

#include <cstddef>
#include <string>

namespace lit
{
    /** \brief A solution improvement. */
    struct SolutionEvent
    {
        /** \brief Planner time (s) at which the solution was found (external-policy time excluded). */
        double time{0.0};
        double cost{0.0};
        /** \brief Number of states on the path. */
        std::size_t pathStates{0u};
        /** \brief 1 for the first solution. */
        std::size_t improvement{0u};
        std::size_t iteration{0u};
    };

    /** \brief One decision of B or psi_K. */
    struct DecisionEvent
    {
        DecisionKind kind{DecisionKind::BatchSize};
        Features features;
        /** \brief Applied value (B as an integer value, psi_K real). */
        double value{0.0};
        /** \brief Resulting neighbour count K (psi_K decisions). */
        std::size_t neighbours{0u};
        std::string policy;
        double time{0.0};
        std::size_t iteration{0u};
    };

    /** \brief A new batch of samples was added. */
    struct BatchEvent
    {
        std::size_t batch{0u};
        std::size_t batchSize{0u};
        std::size_t validSamples{0u};
        std::size_t invalidSamples{0u};
        std::size_t prunedSamples{0u};
        double time{0.0};
    };

    /** \brief Receives planner events; all methods run on the planning thread. */
    class PlannerListener
    {
    public:
        virtual ~PlannerListener() = default;
        virtual void onSolution(const SolutionEvent & /*event*/)
        {
        }
        virtual void onDecision(const DecisionEvent & /*event*/)
        {
        }
        virtual void onBatch(const BatchEvent & /*event*/)
        {
        }
        /** \brief Whether this listener reads the features of B decisions. The path feature
         *  rho_local,B costs a scan around every path state at every improvement; when the policy
         *  needs no features and no listener reads them, LIT* leaves it out and its decision events
         *  carry NaN for it. */
        virtual bool observesFeatures() const
        {
            return true;
        }
    };
}  // namespace lit
