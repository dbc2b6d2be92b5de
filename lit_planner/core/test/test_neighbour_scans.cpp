// The neighbour scans' fast path must answer exactly as a plain scan: a rescan into an empty cache keeps a bound that
// tightens as it goes (RandomGeometricGraph::scanNeighbours), which must drop no sample among the k nearest, ties and
// near-ties included.
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
    /** \brief What the graph answers for the k nearest of \e state, with their distances. */
    std::vector<std::pair<double, const litstar::State *>> scanned(RandomGeometricGraph &graph, litstar::State *state,
                                                                   std::size_t k)
    {
        std::vector<std::pair<double, const litstar::State *>> got;
        for (litstar::State *other : graph.neighbours(state, k))
            got.emplace_back(graph.distance(state, other), other);
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
            std::uniform_real_distribution<double> coordinate(-0.5, 0.5);
            std::uniform_int_distribution<std::size_t> kDraw(1u, 40u);
            const auto addBatch = [&](std::size_t count) {
                for (std::size_t i = 0; i < count; ++i)
                {
                    std::vector<double> x(16u);
                    for (double &v : x)
                        v = scale * (grid ? std::round(coordinate(rng) * 4.0) / 4.0 : coordinate(rng));
                    graph.addValidSample(x);
                }
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
    // Samples on spheres around a centre, some with radii 1e-12 apart (within the bound's margin of each other): the
    // running bound must drop none of those among the k nearest. Then more of them, for the incremental scan.
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
