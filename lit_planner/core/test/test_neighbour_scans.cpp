// The neighbour scans' fast path must answer exactly as a plain scan: a rescan into an empty cache keeps a bound that
// tightens as it goes (RandomGeometricGraph::scanNeighbours), which must drop no sample among the k nearest, ties and
// near-ties included.
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

TEST(FastPaths, NeighbourScansEqualABruteForceScanInR16)
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
            const auto bruteForce = [&](const litstar::State *state, std::size_t k) {
                std::vector<std::pair<double, const litstar::State *>> all;
                for (const auto &other : graph.states())
                    if (other.get() != state)
                        all.emplace_back(graph.distance(state, other.get()), other.get());
                std::sort(all.begin(), all.end(), [](const auto &a, const auto &b) {
                    return a.first != b.first ? a.first < b.first : a.second->id_ < b.second->id_;
                });
                std::vector<std::pair<double, const litstar::State *>> nearest(
                    all.begin(), all.begin() + static_cast<std::ptrdiff_t>(std::min(k, all.size())));
                return nearest;
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
                    const auto range = graph.neighbours(state, k);
                    std::vector<std::pair<double, const litstar::State *>> got;
                    for (std::size_t i = 0; i < range.size(); ++i)
                        got.emplace_back(graph.distance(state, range[i]), range[i]);
                    ASSERT_EQ(got, bruteForce(state, k)) << "scale " << scale << ", round " << round << ", k " << k;
                }
            }
        }
}

TEST(FastPaths, NeighbourScansKeepSamplesWithinRoundingOfTheBoundInR16)
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
        const auto bruteForce = [&](std::size_t k) {
            std::vector<std::pair<double, const litstar::State *>> all;
            for (const auto &other : graph.states())
                if (other.get() != c)
                    all.emplace_back(graph.distance(c, other.get()), other.get());
            std::sort(all.begin(), all.end(), [](const auto &a, const auto &b) {
                return a.first != b.first ? a.first < b.first : a.second->id_ < b.second->id_;
            });
            all.resize(std::min(k, all.size()));
            return all;
        };
        const auto answer = [&](std::size_t k) {
            const auto range = graph.neighbours(c, k);
            std::vector<std::pair<double, const litstar::State *>> got;
            for (std::size_t i = 0; i < range.size(); ++i)
                got.emplace_back(graph.distance(c, range[i]), range[i]);
            return got;
        };
        const std::size_t k = 31u + static_cast<std::size_t>(unit(rng) * 58.0);
        ASSERT_EQ(answer(k), bruteForce(k)) << "trial " << trial << ", k " << k;
        addShell(60, 0.3, 1e-12);  // ties and near-ties of the cached entries
        ASSERT_EQ(answer(k), bruteForce(k)) << "trial " << trial << ", k " << k;
    }
}
