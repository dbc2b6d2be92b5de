#include "lit/litstar/ForwardQueue.h"

#include <algorithm>

namespace lit::litstar
{
    namespace
    {
        void eraseHandle(std::vector<ForwardQueueElement *> &handles, ForwardQueueElement *element)
        {
            auto it = std::find(handles.begin(), handles.end(), element);
            if (it != handles.end())
            {
                *it = handles.back();
                handles.pop_back();
            }
        }
    }  // namespace

    ForwardQueue::ForwardQueue(KeyFunction keys) : keys_(std::move(keys)), heap_(EdgeOrder{&effortFirst_})
    {
    }

    ForwardQueue::~ForwardQueue()
    {
        clear();
    }

    void ForwardQueue::setEffortFirst(bool effortFirst)
    {
        if (effortFirst_ == effortFirst)
            return;
        effortFirst_ = effortFirst;
        heap_.rebuild();
    }

    ForwardQueue::Heap::Element *ForwardQueue::find(const State *source, const State *target) const
    {
        for (auto *element : source->outgoing_)
            if (element->data->target == target)
                return element;
        return nullptr;
    }

    bool ForwardQueue::contains(const State *source, const State *target) const
    {
        return find(source, target) != nullptr;
    }

    void ForwardQueue::insert(State *source, State *target)
    {
        if (contains(source, target))
            return;
        auto *edge = new Edge{source, target, 0.0, 0.0};
        keys_(*edge);
        Heap::Element *element = heap_.insert(edge);
        source->outgoing_.push_back(element);
        target->incoming_.push_back(element);
    }

    const Edge *ForwardQueue::top() const
    {
        return heap_.empty() ? nullptr : heap_.top()->data;
    }

    void ForwardQueue::detach(Heap::Element *element)
    {
        eraseHandle(element->data->source->outgoing_, element);
        eraseHandle(element->data->target->incoming_, element);
    }

    Edge ForwardQueue::pop()
    {
        Heap::Element *element = heap_.top();
        Edge *edge = element->data;
        detach(element);
        heap_.pop();
        Edge copy = *edge;
        delete edge;
        return copy;
    }

    void ForwardQueue::updateIncoming(State *state)
    {
        for (auto *element : state->incoming_)
        {
            keys_(*element->data);
            heap_.update(element);
        }
    }

    void ForwardQueue::updateOutgoing(State *state)
    {
        for (auto *element : state->outgoing_)
        {
            keys_(*element->data);
            heap_.update(element);
        }
    }

    void ForwardQueue::updatePair(State *a, State *b)
    {
        for (auto *element : {find(a, b), find(b, a)})
            if (element != nullptr)
            {
                keys_(*element->data);
                heap_.update(element);
            }
    }

    void ForwardQueue::erase(Heap::Element *element)
    {
        Edge *edge = element->data;
        detach(element);
        heap_.remove(element);
        delete edge;
    }

    void ForwardQueue::removePair(State *a, State *b)
    {
        if (auto *element = find(a, b))
            erase(element);
        if (auto *element = find(b, a))
            erase(element);
    }

    void ForwardQueue::updateAll()
    {
        std::vector<Edge *> edges;
        heap_.getContent(edges);
        for (auto *edge : edges)
            keys_(*edge);
        heap_.rebuild();
    }

    void ForwardQueue::removeEdgesOf(State *state)
    {
        while (!state->outgoing_.empty())
            erase(state->outgoing_.back());
        while (!state->incoming_.empty())
            erase(state->incoming_.back());
    }

    void ForwardQueue::clear()
    {
        std::vector<Edge *> edges;
        heap_.getContent(edges);
        for (auto *edge : edges)
        {
            edge->source->outgoing_.clear();
            edge->target->incoming_.clear();
            delete edge;
        }
        heap_.clear();
    }
}  // namespace lit::litstar
