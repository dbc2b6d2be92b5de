#pragma once
/** \file litstar/Edge.h
 *  \brief An edge of the forward queue with its cached keys. */

namespace lit::litstar
{
    class State;

    /** \brief Directed edge source -> target with the forward-search keys. */
    struct Edge
    {
        State *source{nullptr};
        State *target{nullptr};
        /** \brief g(source) + c_hat(source, target) + h_hat(target). */
        double lowerBoundKey{0.0};
        /** \brief Remaining collision checks on the edge + e_bar(target). */
        double effortKey{0.0};
    };

    /** \brief Strict weak order on edges, lexicographic on (effort, lower bound) or (lower bound, effort). */
    struct EdgeOrder
    {
        const bool *effortFirst{nullptr};
        bool operator()(const Edge *a, const Edge *b) const
        {
            if (*effortFirst)
            {
                if (a->effortKey != b->effortKey)
                    return a->effortKey < b->effortKey;
                return a->lowerBoundKey < b->lowerBoundKey;
            }
            if (a->lowerBoundKey != b->lowerBoundKey)
                return a->lowerBoundKey < b->lowerBoundKey;
            return a->effortKey < b->effortKey;
        }
    };
}  // namespace lit::litstar
