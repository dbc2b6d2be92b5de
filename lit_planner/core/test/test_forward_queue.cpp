/* The forward search's edge queue: re-keying and removing the edges between two states, either way. */
#include "lit/litstar/ForwardQueue.h"
#include "lit/litstar/State.h"

#include <gtest/gtest.h>

#include <map>
#include <utility>

using lit::litstar::Edge;
using lit::litstar::ForwardQueue;
using lit::litstar::State;

namespace
{
    /** Three states and a queue whose effort keys come from a table the test changes. */
    struct QueueFixture
    {
        State a{0u, nullptr, nullptr};
        State b{1u, nullptr, nullptr};
        State c{2u, nullptr, nullptr};
        std::map<std::pair<const State *, const State *>, double> effort;
        ForwardQueue queue{[this](Edge &edge) {
            edge.effortKey = effort.at({edge.source, edge.target});
            edge.lowerBoundKey = 0.0;
        }};

        QueueFixture()
        {
            effort[{&a, &b}] = 5.0;
            effort[{&b, &a}] = 4.0;
            effort[{&a, &c}] = 3.0;
            queue.insert(&a, &b);
            queue.insert(&b, &a);
            queue.insert(&a, &c);
        }
    };
}  // namespace

TEST(ForwardQueue, UpdatePairReKeysBothDirectionsOfAnEdge)
{
    QueueFixture f;
    ASSERT_EQ(f.queue.top()->target, &f.c);
    // A check of the edge a-b left fewer checks on it: both queued directions are cheaper now.
    f.effort[{&f.a, &f.b}] = 0.0;
    f.effort[{&f.b, &f.a}] = 1.0;
    f.queue.updatePair(&f.b, &f.a);
    Edge first = f.queue.pop();
    EXPECT_EQ(first.source, &f.a);
    EXPECT_EQ(first.target, &f.b);
    EXPECT_EQ(first.effortKey, 0.0);
    Edge second = f.queue.pop();
    EXPECT_EQ(second.source, &f.b);
    EXPECT_EQ(second.effortKey, 1.0);
    EXPECT_EQ(f.queue.pop().target, &f.c);
    EXPECT_TRUE(f.queue.empty());
}

TEST(ForwardQueue, UpdatePairWithOneDirectionQueuedReKeysThatOne)
{
    QueueFixture f;
    f.effort[{&f.c, &f.a}] = 0.0;  // c -> a is not queued: nothing to re-key, nothing added
    f.effort[{&f.a, &f.c}] = 10.0;
    f.queue.updatePair(&f.c, &f.a);
    EXPECT_EQ(f.queue.size(), 3u);
    EXPECT_FALSE(f.queue.contains(&f.c, &f.a));
    EXPECT_EQ(f.queue.pop().source, &f.b);  // 4 < 5 < 10
    EXPECT_EQ(f.queue.pop().target, &f.b);
    Edge last = f.queue.pop();
    EXPECT_EQ(last.target, &f.c);
    EXPECT_EQ(last.effortKey, 10.0);
}

TEST(ForwardQueue, RemovePairRemovesBothDirectionsAndNothingElse)
{
    QueueFixture f;
    f.queue.removePair(&f.b, &f.a);
    EXPECT_EQ(f.queue.size(), 1u);
    EXPECT_FALSE(f.queue.contains(&f.a, &f.b));
    EXPECT_FALSE(f.queue.contains(&f.b, &f.a));
    EXPECT_TRUE(f.queue.contains(&f.a, &f.c));
    EXPECT_TRUE(f.b.incoming_.empty());
    EXPECT_TRUE(f.b.outgoing_.empty());
    EXPECT_EQ(f.a.outgoing_.size(), 1u);
    EXPECT_TRUE(f.a.incoming_.empty());
    f.queue.removePair(&f.a, &f.b);  // no longer queued: a no-op
    EXPECT_EQ(f.queue.size(), 1u);
    EXPECT_EQ(f.queue.pop().target, &f.c);
}
