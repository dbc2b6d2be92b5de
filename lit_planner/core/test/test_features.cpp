#include "Nearest.h"
#include "Worlds.h"

#include "lit/litstar/RandomGeometricGraph.h"

#include <ompl/base/ScopedState.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <map>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

using namespace lit;
using litstar::RandomGeometricGraph;

namespace
{
    std::unique_ptr<RandomGeometricGraph> handBuilt(const BoxProblem &problem)
    {
        auto graph = std::make_unique<RandomGeometricGraph>(problem.si, 1u);
        ompl::base::ScopedState<> start(problem.si), goal(problem.si);
        start[0] = -0.2;
        start[1] = 0.0;
        goal[0] = 0.2;
        goal[1] = 0.0;
        graph->setTerminals(start.get(), {goal.get()});
        return graph;
    }
}  // namespace

TEST(Features, GlobalRatioCountsPrunedSetsIncludingTerminals)
{
    BoxProblem problem = test::narrowPassage(2);
    RandomGeometricGraph graph(problem.si, 1u);
    EXPECT_DOUBLE_EQ(graph.ratioCalc(), 0.0);  // no samples at all
    ompl::base::ScopedState<> start(problem.si), goal(problem.si);
    start[0] = -0.2;
    start[1] = 0.0;
    goal[0] = 0.2;
    goal[1] = 0.0;
    graph.setTerminals(start.get(), {goal.get()});
    graph.addValidSample({-0.3, 0.3});
    graph.addValidSample({0.3, 0.3});
    graph.addInvalidSample({0.0, 0.0});
    graph.addInvalidSample({0.0, 0.3});
    EXPECT_EQ(graph.numValid(), 4u);
    EXPECT_EQ(graph.numInvalid(), 2u);
    EXPECT_DOUBLE_EQ(graph.ratioCalc(), 2.0 / 6.0);
}

TEST(Features, LocalRatiosAroundPathStatesAndTheExpandedState)
{
    BoxProblem problem = test::narrowPassage(2);
    auto owner = handBuilt(problem);
    RandomGeometricGraph &graph = *owner;  // valid: start (-0.2, 0), goal (0.2, 0)
    graph.addValidSample({-0.15, 0.0});
    graph.addInvalidSample({-0.05, 0.0});
    graph.addInvalidSample({0.0, 0.0});
    graph.addInvalidSample({0.05, 0.0});
    const litstar::State *isolated = graph.addValidSample({0.0, 0.4});

    ompl::base::ScopedState<> a(problem.si), b(problem.si), lonely(problem.si);
    a[0] = -0.2;   // within 0.06: (-0.15, 0) (the start is at a itself) -> ratio 0
    a[1] = 0.0;
    b[0] = 0.0;    // within 0.06: (-0.05, 0), (0.05, 0) (the invalid (0, 0) is at b itself) -> ratio 1
    b[1] = 0.0;
    lonely[0] = -0.45;
    lonely[1] = -0.45;
    EXPECT_DOUBLE_EQ(graph.localRatio(a.get(), 0.06), 0.0);
    EXPECT_DOUBLE_EQ(graph.localRatio(b.get(), 0.06), 1.0);
    EXPECT_LT(graph.localRatio(lonely.get(), 0.06), 0.0);  // empty neighbourhood
    // A state is not its own neighbour: the valid sample (0, 0.4) has no other sample within 0.06, so its
    // neighbourhood is empty (counting itself it would be 0, "no obstacles around").
    EXPECT_LT(graph.localRatio(isolated->raw_, 0.06), 0.0);
    // The start (-0.2, 0) has (-0.15, 0) only.
    EXPECT_DOUBLE_EQ(graph.localRatio(graph.start()->raw_, 0.06), 0.0);

    const double global = 3.0 / 7.0;
    EXPECT_DOUBLE_EQ(graph.ratioCalc(), global);
    // rho_local,B is the mean over path states; rho_local,K the ratio at the expanded state.
    auto [localB, localK] = graph.localRatioCalc({a.get(), b.get()}, b.get(), 0.06);
    EXPECT_DOUBLE_EQ(localB, 0.5);
    EXPECT_DOUBLE_EQ(localK, 1.0);
    // Fallbacks: no path -> rho_global; empty neighbourhood -> rho_global (also inside the path mean).
    std::tie(localB, localK) = graph.localRatioCalc({}, lonely.get(), 0.06);
    EXPECT_DOUBLE_EQ(localB, global);
    EXPECT_DOUBLE_EQ(localK, global);
    std::tie(localB, localK) = graph.localRatioCalc({a.get(), lonely.get()}, nullptr, 0.06);
    EXPECT_DOUBLE_EQ(localB, (0.0 + global) / 2.0);
    EXPECT_DOUBLE_EQ(localK, global);
    std::tie(localB, localK) = graph.localRatioCalc({a.get(), isolated->raw_}, isolated->raw_, 0.06);
    EXPECT_DOUBLE_EQ(localB, (0.0 + global) / 2.0);
    EXPECT_DOUBLE_EQ(localK, global);
}

TEST(Features, RadiusFollowsTheRggFormula)
{
    BoxProblem problem = test::narrowPassage(2);
    auto owner = handBuilt(problem);
    RandomGeometricGraph &graph = *owner;
    for (int i = 0; i < 98; ++i)
        graph.addValidSample({-0.4 + 0.008 * i, 0.3});
    const double q = 100.0, n = 2.0, informed = 0.5;
    const double expected = 1.1 * std::pow(2.0 * (1.0 + 1.0 / n) * (informed / M_PI) * (std::log(q) / q), 1.0 / n);
    EXPECT_NEAR(graph.radius(1.1, informed), expected, 1e-12);
}

TEST(Features, PruningRemovesWhatCannotImproveAndKeepsTerminals)
{
    BoxProblem problem = test::narrowPassage(2);
    auto owner = handBuilt(problem);
    RandomGeometricGraph &graph = *owner;
    graph.addValidSample({0.0, 0.05});   // heuristic 2 * sqrt(0.04 + 0.0025) = 0.412
    graph.addValidSample({0.0, 0.4});    // heuristic 2 * sqrt(0.04 + 0.16) = 0.894
    graph.addInvalidSample({0.0, 0.1});  // 0.447
    graph.addInvalidSample({0.3, 0.4});  // 0.412 + ... > 0.6
    std::size_t callbacks = 0u;
    const std::size_t removed = graph.prune(0.5, [&](litstar::State *) { ++callbacks; });
    EXPECT_EQ(removed, 2u);
    EXPECT_EQ(callbacks, 1u);
    EXPECT_EQ(graph.numValid(), 3u);
    EXPECT_EQ(graph.numInvalid(), 1u);
    EXPECT_NE(graph.start(), nullptr);
    EXPECT_EQ(graph.goals().size(), 1u);
    // A pinned sample (LIT* pins its best path's) stays whatever its heuristic.
    litstar::State *pinned = graph.addValidSample({0.0, 0.45});  // heuristic 2 * sqrt(0.04 + 0.2025) = 0.985
    pinned->pinned_ = true;
    graph.addValidSample({0.0, -0.45});
    EXPECT_EQ(graph.prune(0.5, [](litstar::State *) {}), 1u);
    EXPECT_EQ(graph.numValid(), 4u);
    EXPECT_TRUE(std::any_of(graph.states().begin(), graph.states().end(),
                            [pinned](const auto &state) { return state.get() == pinned; }));
}

TEST(Features, IncomingNeighboursMakeTheKNearestGraphSymmetric)
{
    BoxProblem problem = test::narrowPassage(2);
    auto owner = handBuilt(problem);
    RandomGeometricGraph &graph = *owner;
    // A tight cluster near the start and one far sample: the far sample's nearest are in the cluster, but no
    // cluster member has the far sample among its nearest.
    litstar::State *a = graph.addValidSample({-0.30, 0.30});
    litstar::State *b = graph.addValidSample({-0.31, 0.30});
    litstar::State *c = graph.addValidSample({-0.30, 0.31});
    litstar::State *far = graph.addValidSample({0.45, -0.45});
    const auto contains = [](const auto &list, const litstar::State *s) {
        return std::find(list.begin(), list.end(), s) != list.end();
    };
    EXPECT_TRUE(graph.incomingNeighbours(a).empty());  // nothing computed yet
    const auto &nearest = graph.neighbours(far, 2u);
    ASSERT_EQ(nearest.size(), 2u);
    for (litstar::State *s : {a, b, c})
        EXPECT_EQ(contains(nearest, s), contains(graph.incomingNeighbours(s), far));
    for (litstar::State *s : {a, b, c})
        EXPECT_FALSE(contains(graph.neighbours(s, 2u), far));
    // A recomputed list with a smaller k drops the entry from the incoming side too.
    const auto &closest = graph.neighbours(far, 1u);
    ASSERT_EQ(closest.size(), 1u);
    for (litstar::State *s : {a, b, c})
        EXPECT_EQ(s == closest.front(), contains(graph.incomingNeighbours(s), far));
    // Pruning the far sample (heuristic 1.30; the cluster's is about 0.9) clears the incoming lists, which would
    // otherwise name it.
    EXPECT_EQ(graph.prune(1.0, [](litstar::State *) {}), 1u);
    for (litstar::State *s : {a, b, c})
        EXPECT_TRUE(graph.incomingNeighbours(s).empty());
}

TEST(Features, NeighbourCacheEqualsABruteForceScanWhateverTheSequenceOfK)
{
    // Samples arrive in batches, k goes up and down as a learned policy's psi_K does, and a prune removes samples
    // (shifting the positions of the rest): every answer must equal a fresh exact scan, with distance()'s distances
    // to the bit, and the incoming lists must mirror the k last asked, with their distances. In R^4 and in R^11
    // (the scans' single-precision filter, its rows padded to 12 values and rebuilt by the prune).
    for (const unsigned int dim : {4u, 11u})
    {
        BoxProblem problem = test::narrowPassage(dim);
        RandomGeometricGraph graph(problem.si, 1u);
        std::mt19937 rng(7u);
        std::uniform_int_distribution<std::size_t> kDraw(1u, 14u);
        // A few exact duplicates and equal distances exercise the tie order (distance, then id).
        const auto addBatch = [&](std::size_t count) { test::addRandomSamples(graph, rng, count, dim, 8.0); };
        const auto bruteForce = [&](const litstar::State *state, std::size_t k) {
            std::vector<const litstar::State *> nearest;
            for (const auto &[distance, other] : test::nearestByBruteForce(graph, state, k))
                nearest.push_back(other);
            return nearest;
        };
        std::map<const litstar::State *, std::vector<const litstar::State *>> lastAnswer;
        for (int round = 0; round < 12; ++round)
        {
            // Round 0 starts with fewer samples than most k: caches that are not full, prefixes that are the whole
            // cache, k above the number of samples.
            addBatch(round == 0 ? 6u : 15u);
            if (round == 6)
            {
                // Remove a quarter of the samples (by id), as a prune would; the cached lists must not name them.
                std::vector<const litstar::State *> doomed;
                for (const auto &state : graph.states())
                    if (state->id_ % 4u == 1u)
                        doomed.push_back(state.get());
                for (const auto &state : graph.states())
                {
                    state->costToComeLowerBound_ = state->id_ % 4u == 1u ? 10.0 : 0.0;
                    state->costToGoLowerBound_ = 0.0;
                }
                ASSERT_EQ(graph.prune(5.0, [](litstar::State *) {}), doomed.size());
                lastAnswer.clear();  // a prune clears the incoming lists: nothing has been asked in the new epoch
            }
            for (int query = 0; query < 40; ++query)
            {
                auto &states = graph.states();
                std::uniform_int_distribution<std::size_t> pick(0u, states.size() - 1u);
                litstar::State *state = states[pick(rng)].get();
                const std::size_t k = kDraw(rng);
                const auto range = graph.neighbours(state, k);
                const std::vector<const litstar::State *> got(range.begin(), range.end());
                ASSERT_EQ(got, bruteForce(state, k)) << "dim " << dim << ", round " << round << ", k " << k;
                for (std::size_t i = 0; i < range.size(); ++i)
                    ASSERT_EQ(range.distances()[i], graph.distance(state, range[i]))
                        << "dim " << dim << ", round " << round;
                lastAnswer[state] = got;
            }
            // Incoming lists: s names t exactly when s was in t's last answer (the k nearest as last asked for,
            // possibly before later batches).
            for (const auto &s : graph.states())
            {
                std::vector<const litstar::State *> expected;
                for (const auto &[t, answer] : lastAnswer)
                    if (std::find(answer.begin(), answer.end(), s.get()) != answer.end())
                        expected.push_back(t);
                const auto &incoming = graph.incomingNeighbours(s.get());
                const auto &distances = graph.incomingDistances(s.get());
                ASSERT_EQ(distances.size(), incoming.size());
                for (std::size_t i = 0; i < incoming.size(); ++i)
                    ASSERT_EQ(distances[i], graph.distance(s.get(), incoming[i]))
                        << "dim " << dim << ", round " << round;
                std::vector<const litstar::State *> got(incoming.begin(), incoming.end());
                std::sort(got.begin(), got.end());
                std::sort(expected.begin(), expected.end());
                ASSERT_EQ(got, expected) << "dim " << dim << ", round " << round;
            }
        }
    }
}

TEST(Features, LocalRatioCountsASampleExactlyAtTheRadius)
{
    // The count uses squared distances with a sqrt only near the radius: a sample at exactly distance() counts,
    // with one ulp less of radius it does not, for valid and invalid samples alike. One sample of the other kind
    // sits next to the centre (not at it: a sample at the centre is the centre itself), so each count shows in
    // the ratio.
    BoxProblem problem = test::narrowPassage(4);
    RandomGeometricGraph graph(problem.si, 1u);
    std::mt19937 rng(11u);
    std::uniform_real_distribution<double> coordinate(-0.5, 0.5);
    ompl::base::ScopedState<> centre(problem.si);
    for (int trial = 0; trial < 400; ++trial)
    {
        std::vector<double> c(4u), x(4u);
        for (unsigned int i = 0; i < 4u; ++i)
        {
            c[i] = coordinate(rng);
            x[i] = coordinate(rng);
            centre[i] = c[i];
        }
        graph.clear();
        std::vector<double> beside = c;
        beside[0] += 1e-6;
        const bool validProbe = trial % 2 == 0;
        if (validProbe)
        {
            graph.addValidSample(x);
            graph.addInvalidSample(beside);
        }
        else
        {
            graph.addInvalidSample(x);
            graph.addValidSample(beside);
        }
        const double d = graph.distance(c.data(), x.data());
        ASSERT_GT(d, 1e-5) << trial;
        const double with = graph.localRatio(centre.get(), d);
        const double without = graph.localRatio(centre.get(), std::nextafter(d, 0.0));
        EXPECT_DOUBLE_EQ(with, 0.5) << trial;
        EXPECT_DOUBLE_EQ(without, validProbe ? 1.0 : 0.0) << trial;
    }
}
