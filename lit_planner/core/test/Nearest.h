#pragma once
// The exact k nearest by brute force, for the tests of the neighbour caches and scans.
#include "lit/litstar/RandomGeometricGraph.h"

#include <algorithm>
#include <utility>
#include <vector>

namespace lit::test
{
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
