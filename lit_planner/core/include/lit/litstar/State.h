#pragma once
/** \file litstar/State.h
 *  \brief A valid sample of LIT*'s random geometric graph, with its search data. */

#include "lit/litstar/Edge.h"

#include <ompl/base/State.h>
#include <ompl/datastructures/BinaryHeap.h>

#include <cstddef>
#include <limits>
#include <unordered_map>
#include <unordered_set>
#include <vector>

namespace lit::litstar
{
    /** \brief Heap element handle of the forward queue. */
    using ForwardQueueElement = ompl::BinaryHeap<Edge *, EdgeOrder>::Element;

    /** \brief A valid sample: state, heuristics, reverse-search values, forward-tree links, edge knowledge. */
    class State
    {
    public:
        static constexpr double infinity = std::numeric_limits<double>::infinity();

        State(std::size_t id, ompl::base::State *raw, const double *coordinates)
          : id_(id), raw_(raw), coordinates_(coordinates)
        {
        }

        /** \brief Unique id within the graph. */
        std::size_t id_;
        /** \brief The OMPL state (owned by the graph). */
        ompl::base::State *raw_;
        /** \brief Its R^n coordinates (inside raw_). */
        const double *coordinates_;

        /** \brief Admissible cost from the start (straight line), \hat g_lb. */
        double costToComeLowerBound_{infinity};
        /** \brief Admissible cost to the goal (straight line), \hat h_lb. */
        double costToGoLowerBound_{infinity};
        bool isStart_{false};
        bool isGoal_{false};

        /** \brief Reverse search: values are valid only while reverseTag_ equals the graph's current tag,
         *  so restarting the reverse search is O(1). */
        unsigned int reverseTag_{0u};
        /** \brief Admissible cost-to-go \hat h over sparsely checked edges (\bar h equals it for path length). */
        double reverseCost_{infinity};
        /** \brief Estimated remaining collision checks to the goal, \bar e. */
        double reverseEffort_{infinity};
        /** \brief Parent towards the goal in the reverse tree. */
        State *reverseParent_{nullptr};
        /** \brief The k of this state's latest offer of its reverse edges (its reverse expansion, or a forward
         *  expansion with a larger k), valid while reverseTag_ is current. */
        std::size_t reverseK_{0u};

        /** \brief Forward tree: cost-to-come g, parent, children, and the cost of the parent edge. */
        double costToCome_{infinity};
        State *forwardParent_{nullptr};
        std::vector<State *> forwardChildren_;
        double parentEdgeCost_{0.0};

        /** \brief Edges proven valid / invalid, by neighbour id. */
        std::unordered_set<std::size_t> whitelist_;
        std::unordered_set<std::size_t> blacklist_;
        /** \brief Bisection depth already checked on the edge to a neighbour (kept on the smaller id). */
        std::unordered_map<std::size_t, unsigned int> checkedDepth_;

        /** \brief Nearest-neighbour cache with distances, sorted by (distance, id): the neighboursCap_ nearest
         *  samples, of which the first neighboursK_ (the k last asked for) are the current k nearest. Valid until
         *  the graph is cleared: a prune filters the removed samples out, samples appended since (index >=
         *  neighboursScanned_) are merged in incrementally, and any k up to the cap is a prefix, so a policy that
         *  changes k does not force a rescan. */
        std::vector<State *> neighbours_;
        std::vector<double> neighbourDistances_;
        std::size_t neighboursEpoch_{std::numeric_limits<std::size_t>::max()};
        std::size_t neighboursK_{0u};
        std::size_t neighboursCap_{0u};
        std::size_t neighboursScanned_{0u};
        /** \brief The graph's incoming epoch in which this sample's prefix was last registered. */
        std::size_t incomingEpoch_{std::numeric_limits<std::size_t>::max()};
        /** \brief Set by a prune on the samples it removes, while the caches are filtered. */
        bool pruned_{false};
        /** \brief Never pruned (LIT* pins its best path's samples). */
        bool pinned_{false};
        /** \brief Samples whose k-nearest list (as last asked for) contains this sample: with them an edge found
         *  from either end is seen from both. The searched graph is therefore the k-nearest lists computed so far,
         *  made symmetric; a sample whose own list has not been computed contributes no edges of its own (not the
         *  full undirected k-nearest graph). Entries whose list has dropped this sample since are removed when
         *  read. */
        std::vector<State *> incomingNeighbours_;
        /** \brief Their distances to this sample (each the one in its owner's cache, equal to distance() to the
         *  bit), parallel to incomingNeighbours_. */
        std::vector<double> incomingDistances_;
        /** \brief The planner's mark while it collects a neighbour list (equal to its current stamp: listed). */
        std::size_t collectMark_{0u};

        /** \brief Forward-queue edges leaving / entering this state (for re-keying). */
        std::vector<ForwardQueueElement *> outgoing_;
        std::vector<ForwardQueueElement *> incoming_;

        /** \brief Current reverse cost, infinite when the state is not in the current reverse tree. */
        double reverseCost(unsigned int tag) const
        {
            return reverseTag_ == tag ? reverseCost_ : infinity;
        }
        double reverseEffort(unsigned int tag) const
        {
            return reverseTag_ == tag ? reverseEffort_ : infinity;
        }
        State *reverseParent(unsigned int tag) const
        {
            return reverseTag_ == tag ? reverseParent_ : nullptr;
        }
        bool isInForwardTree() const
        {
            return isStart_ || forwardParent_ != nullptr;
        }
    };
}  // namespace lit::litstar
