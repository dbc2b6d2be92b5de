// The neighbour scans' fast paths must answer exactly as a plain scan (RandomGeometricGraph::scanNeighbours): a rescan
// into an empty cache keeps a bound that tightens as it goes, and in R^9 and up a single-precision sum with an error
// bound drops samples before the double one. Neither may drop a sample among the k nearest, ties and near-ties
// included, and the cached distances must be distance()'s to the bit (the searches take edge lengths from them).
#include "Nearest.h"
#include "Worlds.h"

#include "lit/litstar/RandomGeometricGraph.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

using namespace lit;
using litstar::RandomGeometricGraph;

namespace
{
    /** \brief What the graph answers for the k nearest of \e state, with the distances it has cached for them. */
    std::vector<std::pair<double, const litstar::State *>> scanned(RandomGeometricGraph &graph, litstar::State *state,
                                                                   std::size_t k)
    {
        const auto range = graph.neighbours(state, k);
        std::vector<std::pair<double, const litstar::State *>> got;
        for (std::size_t i = 0; i < range.size(); ++i)
            got.emplace_back(range.distances()[i], range[i]);
        return got;
    }
}  // namespace

TEST(NeighbourScans, NeighbourScansEqualABruteForceScanInR16)
{
    // As Features.NeighbourCacheEqualsABruteForceScanWhateverTheSequenceOfK, in R^16 and at several scales of the
    // coordinates (also on a coarse grid: many exact ties), with enough samples for the running bound.
    for (const double scale : {1.0, 1e-3, 1e3})
        for (const bool grid : {true, false})
        {
            BoxProblem problem = test::narrowPassage(16);
            RandomGeometricGraph graph(problem.si, 1u);
            std::mt19937 rng(9u);
            std::uniform_int_distribution<std::size_t> kDraw(1u, 40u);
            const auto addBatch = [&](std::size_t count) {
                test::addRandomSamples(graph, rng, count, 16u, grid ? 4.0 : 0.0, scale);
            };
            for (int round = 0; round < 8; ++round)
            {
                addBatch(round == 0 ? 10u : 120u);
                for (int query = 0; query < 30; ++query)
                {
                    auto &states = graph.states();
                    std::uniform_int_distribution<std::size_t> pick(0u, states.size() - 1u);
                    litstar::State *state = states[pick(rng)].get();
                    const std::size_t k = kDraw(rng);
                    ASSERT_EQ(scanned(graph, state, k), test::nearestByBruteForce(graph, state, k))
                        << "scale " << scale << ", round " << round << ", k " << k;
                }
            }
        }
}

TEST(NeighbourScans, NeighbourScansKeepSamplesWithinRoundingOfTheBoundInR16)
{
    // Samples on spheres around a centre, some with radii 1e-12 apart (within the bound's margin of each other,
    // and far below single precision): neither the running bound nor the filter may drop one of those among the
    // k nearest. Then more of them, for the incremental scan.
    std::mt19937 rng(3u);
    std::normal_distribution<double> normal;
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int trial = 0; trial < 20; ++trial)
    {
        BoxProblem problem = test::narrowPassage(16);
        RandomGeometricGraph graph(problem.si, 1u);
        std::vector<double> centre(16u);
        for (double &v : centre)
            v = unit(rng) - 0.5;
        litstar::State *c = graph.addValidSample(centre);
        const auto addShell = [&](int count, double radius, double spacing) {
            for (int j = 0; j < count; ++j)
            {
                std::vector<double> direction(16u);
                double norm = 0.0;
                for (double &v : direction)
                {
                    v = normal(rng);
                    norm += v * v;
                }
                const double r = radius * (1.0 + spacing * static_cast<double>(j));
                std::vector<double> x(16u);
                for (unsigned int i = 0; i < 16u; ++i)
                    x[i] = centre[i] + r * direction[i] / std::sqrt(norm);
                graph.addValidSample(x);
            }
        };
        addShell(30, 0.1, 1e-3);
        addShell(60, 0.3, 1e-12);
        addShell(300, 1.0, 1e-3);
        const std::size_t k = 31u + static_cast<std::size_t>(unit(rng) * 58.0);
        ASSERT_EQ(scanned(graph, c, k), test::nearestByBruteForce(graph, c, k)) << "trial " << trial << ", k " << k;
        addShell(60, 0.3, 1e-12);  // ties and near-ties of the cached entries
        ASSERT_EQ(scanned(graph, c, k), test::nearestByBruteForce(graph, c, k)) << "trial " << trial << ", k " << k;
    }
}

TEST(NeighbourScans, ANaNCoordinateTurnsTheSinglePrecisionFilterOff)
{
    // The filter's error bound rests on the largest |coordinate| so far. A NaN must keep it off (a later coordinate
    // of 0.5 once replaced the NaN as that bound, and a sample 0.032 away, rounded to 0.0625 in single precision, was
    // dropped for one 0.04 away). A NaN can come in through addValidSample or a checker that lets one through.
    BoxProblem problem = test::narrowPassage(12);
    RandomGeometricGraph graph(problem.si, 1u);
    std::vector<double> query(12u, 0.0);
    query[0] = 1e6;
    litstar::State *q = graph.addValidSample(query);
    for (int j = 0; j < 200; ++j)
    {
        std::vector<double> filler(query);
        filler[1] = 0.04 + 1e-4 * j;
        graph.addValidSample(filler);
    }
    std::vector<double> nearest(query);
    nearest[0] = 1e6 + 0.032;
    litstar::State *y = graph.addValidSample(nearest);
    std::vector<double> nan(12u, 0.0);
    nan[0] = std::nan("");
    nan[1] = 0.5;
    litstar::State *n = graph.addValidSample(nan);
    for (int j = 0; j < 5; ++j)
        graph.addValidSample(std::vector<double>(12u, 0.0));
    // The NaN sample a goal and the query the start: the NaN distance stays out of the selection.
    q->isStart_ = true;
    n->isGoal_ = true;
    const auto range = graph.neighbours(q, 3u);
    ASSERT_EQ(range.size(), 3u);
    EXPECT_EQ(range[0], y);
}

TEST(NeighbourScans, GoalsAddedLaterLowerEveryBoundAndTheSamplersMinimumAndJoinTheScans)
{
    // RandomGeometricGraph::addGoals (a goal region sampled again): every sample's cost-to-go bound is its distance to
    // the nearest goal, old or new; the informed sampler's minimum is the new nearest straight line; a new goal is a
    // goal to the scans (not among another goal's neighbours) and is found by the caches built before it came.
    BoxProblem problem = test::narrowPassage(4);
    RandomGeometricGraph graph(problem.si, 1u);
    ompl::base::ScopedState<> start(problem.si), far(problem.si), near(problem.si);
    start = std::vector<double>{-0.2, 0.0, 0.0, 0.0};
    far = std::vector<double>{0.4, 0.4, 0.0, 0.0};
    near = std::vector<double>{0.2, 0.0, 0.0, 0.0};
    graph.setTerminals(start.get(), {far.get()});
    std::mt19937 rng(5u);
    test::addRandomSamples(graph, rng, 300u, 4u, 0.0);
    litstar::State *sample = graph.states().back().get();
    const std::size_t k = 20u;
    scanned(graph, sample, k);  // a cache from before the new goal
    graph.addGoals({near.get()});
    ASSERT_EQ(graph.goals().size(), 2u);
    const litstar::State *added = graph.goals()[1];
    EXPECT_TRUE(added->isGoal_);
    EXPECT_DOUBLE_EQ(graph.sampler().minimumCost(), 0.4);
    for (const auto &state : graph.states())
        EXPECT_EQ(state->costToGoLowerBound_,
                  std::min(graph.distance(state.get(), graph.goals()[0]), graph.distance(state.get(), added)));
    EXPECT_EQ(added->costToGoLowerBound_, 0.0);
    ASSERT_EQ(scanned(graph, sample, k), test::nearestByBruteForce(graph, sample, k));
    for (const auto &[distance, neighbour] : scanned(graph, graph.goals()[0], k))
        EXPECT_NE(neighbour, added);  // no edge between two goals
}
