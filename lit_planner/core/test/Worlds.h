#pragma once
// Hand-built worlds for the unit tests (the scenario registry proper lives in Python).
#include "lit/BoxWorld.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace lit::test
{
    /** \brief Narrow passage in R^n: wall x0 in [-0.1, 0.1] with a free slab 0.05 < x1 < 0.15. */
    inline BoxProblem narrowPassage(unsigned int n, double resolution = 5e-6)
    {
        BoxWorld world;
        world.lower.assign(n, -0.5);
        world.upper.assign(n, 0.5);
        Box below{std::vector<double>(n, -0.5), std::vector<double>(n, 0.5)};
        below.lower[0] = -0.1;
        below.upper[0] = 0.1;
        below.upper[1] = 0.05;
        Box above = below;
        above.lower[1] = 0.15;
        above.upper[1] = 0.5;
        world.boxes = {below, above};
        std::vector<double> start(n, 0.0), goal(n, 0.0);
        start[0] = -0.2;
        goal[0] = 0.2;
        return makeBoxProblem(world, start, goal, resolution);
    }

    inline double narrowPassageOptimum()
    {
        return 0.2 + 2.0 * std::sqrt(0.1 * 0.1 + 0.05 * 0.05);
    }

    /** \brief Independent dense re-check of a path: every segment at 1/4 of the planners' resolution. */
    inline bool pathIsValid(const BoxProblem &problem, const std::vector<std::vector<double>> &path)
    {
        const double step = problem.si->getStateValidityCheckingResolution() *
                            problem.si->getMaximumExtent() / 4.0;
        for (std::size_t i = 0; i + 1 < path.size(); ++i)
        {
            const auto &a = path[i];
            const auto &b = path[i + 1];
            double length = 0.0;
            for (std::size_t d = 0; d < a.size(); ++d)
                length += (b[d] - a[d]) * (b[d] - a[d]);
            length = std::sqrt(length);
            const auto steps = static_cast<std::size_t>(std::ceil(length / step));
            std::vector<double> x(a.size());
            for (std::size_t s = 0; s <= steps; ++s)
            {
                const double t = steps == 0u ? 0.0 : static_cast<double>(s) / static_cast<double>(steps);
                for (std::size_t d = 0; d < a.size(); ++d)
                    x[d] = a[d] + t * (b[d] - a[d]);
                if (!problem.checker->isValidPoint(x.data()))
                    return false;
            }
        }
        return true;
    }
    /** \brief Whether \a call throws an \a E whose message contains \a words: a test of bad input also checks
     *  which check refused it (one check firing for every case would pass a bare EXPECT_THROW). */
    template <typename E, typename Call>
    ::testing::AssertionResult throwsWith(Call &&call, const std::string &words)
    {
        try
        {
            call();
        }
        catch (const E &error)
        {
            const std::string message = error.what();
            if (message.find(words) != std::string::npos)
                return ::testing::AssertionSuccess();
            return ::testing::AssertionFailure() << "the message \"" << message << "\" lacks \"" << words << "\"";
        }
        catch (const std::exception &error)
        {
            return ::testing::AssertionFailure() << "another exception: " << error.what();
        }
        return ::testing::AssertionFailure() << "nothing thrown";
    }
}  // namespace lit::test
