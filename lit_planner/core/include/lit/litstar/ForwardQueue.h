#pragma once
/** \file litstar/ForwardQueue.h
 *  \brief The forward search's edge queue. With suboptimality factor epsilon = infinity (before the first
 *  solution) the front is the edge of least estimated effort; with epsilon = 1 it is the edge of least
 *  lower-bound cost (A*-like). Keys are re-computed when a state's cost-to-come or cost-to-go changes. */

#include "lit/litstar/Edge.h"
#include "lit/litstar/State.h"

#include <ompl/datastructures/BinaryHeap.h>

#include <functional>

namespace lit::litstar
{
    class ForwardQueue
    {
    public:
        /** \brief Computes both keys of an edge from the current search values. */
        using KeyFunction = std::function<void(Edge &)>;

        explicit ForwardQueue(KeyFunction keys);
        ~ForwardQueue();
        ForwardQueue(const ForwardQueue &) = delete;
        ForwardQueue &operator=(const ForwardQueue &) = delete;

        /** \brief epsilon = infinity (true) or epsilon = 1 (false); reorders the queue. */
        void setEffortFirst(bool effortFirst);
        bool isEffortFirst() const
        {
            return effortFirst_;
        }

        /** \brief Whether the edge source -> target is queued. */
        bool contains(const State *source, const State *target) const;

        /** \brief Queues source -> target (no-op when already queued). */
        void insert(State *source, State *target);

        /** \brief Front edge or nullptr. */
        const Edge *top() const;

        /** \brief Removes and returns the front edge. */
        Edge pop();

        /** \brief Re-keys the queued edges entering / leaving \e state. */
        void updateIncoming(State *state);
        void updateOutgoing(State *state);

        /** \brief Re-keys source -> target and target -> source where queued (after a check of the edge between
         *  them changed its remaining checks). */
        void updatePair(State *a, State *b);

        /** \brief Removes source -> target and target -> source where queued (the edge between them is invalid). */
        void removePair(State *a, State *b);

        /** \brief Re-keys every edge (after the reverse search restarts). */
        void updateAll();

        /** \brief Removes every queued edge that touches \e state. */
        void removeEdgesOf(State *state);

        void clear();
        bool empty() const
        {
            return heap_.empty();
        }
        std::size_t size() const
        {
            return heap_.size();
        }

    private:
        using Heap = ompl::BinaryHeap<Edge *, EdgeOrder>;
        void detach(Heap::Element *element);
        Heap::Element *find(const State *source, const State *target) const;
        void erase(Heap::Element *element);

        KeyFunction keys_;
        bool effortFirst_{true};
        Heap heap_;
    };
}  // namespace lit::litstar
