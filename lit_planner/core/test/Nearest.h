#pragma once
// The exact k nearest by brute force, and random samples, for the tests of the neighbour caches and scans.
#include "lit/litstar/RandomGeometricGraph.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

namespace lit::test
{
    /** \brief Adds \e count valid samples in R^dim, each coordinate uniform in [-0.5, 0.5], rounded to a multiple of
     *  1 / \e steps when \e steps > 0 (a coarse grid: exact duplicates and equal distances), then times \e scale. */
    inline void addRandomSamples(litstar::RandomGeometricGraph &graph, std::mt19937 &rng, std::size_t count,
                                 unsigned int dim, double steps, double scale = 1.0)
    {
        std::uniform_real_distribution<double> coordinate(-0.5, 0.5);
        for (std::size_t i = 0; i < count; ++i)
        {
            std::vector<double> x(dim);
            for (double &v : x)
                v = scale * (steps > 0.0 ? std::round(coordinate(rng) * steps) / steps : coordinate(rng));
            graph.addValidSample(x);
        }
    }

    /** \brief The k samples of \e graph nearest to \e state (itself left out) with their distances, in the
     *  graph's order: distance, then id. */
    inline std::vector<std::pair<double, const litstar::State *>> nearestByBruteForce(
        const litstar::RandomGeometricGraph &graph, const litstar::State *state, std::size_t k)
    {
        std::vector<std::pair<double, const litstar::State *>> all;
        for (const auto &other : graph.states())
            if (other.get() != state)
                all.emplace_back(graph.distance(state, other.get()), other.get());
        std::sort(all.begin(), all.end(), [](const auto &a, const auto &b) {
            return a.first != b.first ? a.first < b.first : a.second->id_ < b.second->id_;
        });
        all.resize(std::min(k, all.size()));
        return all;
    }
}  // namespace lit::test
