#include "Worlds.h"

#include <ompl/base/ScopedState.h>

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

using namespace lit;

TEST(BoxWorld, ClosedBoxesBoundsAndCounting)
{
    BoxProblem problem = test::narrowPassage(2);
    const double inWall[] = {0.0, 0.0}, onWallFace[] = {0.1, 0.0}, inSlab[] = {0.0, 0.1}, onSlabEdge[] = {0.0, 0.05},
                 outOfBounds[] = {0.6, 0.0}, nan[] = {std::nan(""), 0.0};
    EXPECT_FALSE(problem.checker->isValidPoint(inWall));
    EXPECT_FALSE(problem.checker->isValidPoint(onWallFace));  // closed boxes
    EXPECT_TRUE(problem.checker->isValidPoint(inSlab));
    EXPECT_FALSE(problem.checker->isValidPoint(onSlabEdge));
    EXPECT_FALSE(problem.checker->isValidPoint(outOfBounds));
    EXPECT_FALSE(problem.checker->isValidPoint(nan));
    EXPECT_EQ(problem.checker->calls(), 0u);  // isValidPoint does not count

    ompl::base::ScopedState<> state(problem.si);
    state[0] = 0.0;
    state[1] = 0.1;
    EXPECT_TRUE(problem.si->isValid(state.get()));
    state[1] = 0.0;
    EXPECT_FALSE(problem.si->isValid(state.get()));
    EXPECT_EQ(problem.checker->calls(), 2u);
    problem.checker->resetCalls();
    EXPECT_EQ(problem.checker->calls(), 0u);
}

TEST(BoxWorld, RejectsInconsistentWorlds)
{
    using test::throwsWith;
    BoxWorld world;
    world.lower = {-0.5, -0.5};
    world.upper = {0.5};
    auto dimension = [&world] { static_cast<void>(world.validatedDimension()); };
    EXPECT_TRUE(throwsWith<std::invalid_argument>(dimension, "lower and upper must be non-empty and of equal length"));
    world.upper = {0.5, -0.6};
    EXPECT_TRUE(throwsWith<std::invalid_argument>(dimension, "world bounds: axis 1 needs finite lower < upper"));
    world.upper = {0.5, 0.5};
    world.boxes.push_back(Box{{0.0}, {0.1}});
    EXPECT_TRUE(throwsWith<std::invalid_argument>(dimension, "box 0: corner dimension differs from the world's"));
    world.boxes = {Box{{0.2, 0.0}, {0.1, 0.1}}};
    EXPECT_TRUE(throwsWith<std::invalid_argument>(dimension, "box 0: axis 0 needs finite lower <= upper"));
    world.boxes = {Box{{0.0, 0.0}, {0.1, 0.1}}};
    EXPECT_EQ(world.validatedDimension(), 2u);
    EXPECT_TRUE(throwsWith<std::invalid_argument>([&] { makeBoxProblem(world, {0.0}, {0.0, 0.0}, 1e-3); },
                                                  "start and goal must have the world's dimension 2"));
    EXPECT_TRUE(throwsWith<std::invalid_argument>([&] { makeBoxProblem(world, {0.0, 0.0}, {0.0, 0.0}, 0.0); },
                                                  "resolution must be in (0, 1)"));
}

TEST(BoxWorld, ExactMotionValidationSeesThinWallsAndClippedCorners)
{
    // A 10 x 10 room cut by a 2 mm wall, and a box whose corner a segment clips by 1e-4: at the resolution 1e-3
    // (checks 10 mm apart) the discrete validator passes both; the exact one refuses both.
    BoxWorld world;
    world.lower = {0.0, 0.0};
    world.upper = {10.0, 10.0};
    world.boxes = {Box{{5.0, 0.0}, {5.002, 4.0}}, Box{{2.0, 6.0}, {3.0, 7.0}}};
    BoxProblem discrete = makeBoxProblem(world, {1.0, 1.0}, {9.0, 1.0}, 1e-3);
    BoxProblem exact = makeBoxProblem(world, {1.0, 1.0}, {9.0, 1.0}, 1e-3, true);
    auto validator = std::dynamic_pointer_cast<BoxWorldMotionValidator>(exact.si->getMotionValidator());
    ASSERT_NE(validator, nullptr);
    ompl::base::ScopedState<> a(exact.si), b(exact.si);
    auto check = [&](const BoxProblem &problem, std::vector<double> from, std::vector<double> to) {
        a[0] = from[0], a[1] = from[1], b[0] = to[0], b[1] = to[1];
        return problem.si->checkMotion(a.get(), b.get());
    };
    const std::vector<double> left{4.0047, 1.0}, right{6.0047, 1.0};  // through the thin wall, between points
    EXPECT_TRUE(check(discrete, left, right));
    EXPECT_FALSE(check(exact, left, right));
    // The corner (3, 6) clipped: (2.9, 5.9) -> (3.1, 6.1001) is inside the box for t in [0.49975, 0.5] only,
    // 7e-5 long, between two of the discrete validator's points.
    const std::vector<double> below{2.9, 5.9}, beyond{3.1, 6.1001};
    EXPECT_TRUE(check(discrete, below, beyond));
    EXPECT_FALSE(check(exact, below, beyond));
    EXPECT_TRUE(check(exact, below, {3.1, 6.0999}));  // passes the corner outside
    // Touching a face is a contact (closed boxes), a miss by a hair is not.
    EXPECT_FALSE(check(exact, {1.0, 4.0}, {9.0, 4.0}));
    EXPECT_TRUE(check(exact, {1.0, 4.0 + 1e-9}, {9.0, 4.0 + 1e-9}));
    EXPECT_TRUE(check(exact, {1.0, 5.0}, {9.0, 5.0}));
    // The last valid state lies just before the first box met.
    std::pair<ompl::base::State *, double> last{exact.si->allocState(), 0.0};
    a[0] = 4.0, a[1] = 1.0, b[0] = 6.0, b[1] = 1.0;
    EXPECT_FALSE(validator->checkMotion(a.get(), b.get(), last));
    EXPECT_NEAR(last.second, 0.5, 1e-8);  // the wall at x = 5, half-way
    EXPECT_TRUE(exact.si->isValid(last.first));
    exact.si->freeState(last.first);
    // An end state in collision or out of bounds.
    EXPECT_FALSE(check(exact, {1.0, 1.0}, {5.001, 1.0}));
    EXPECT_FALSE(check(exact, {1.0, 1.0}, {11.0, 1.0}));
    // The last valid state is valid also when the end is out of bounds with no box in the way, when the
    // segment meets a face at a grazing angle (backing off by 1e-9 of it stays on the face), and when the end is
    // not a number (s1 itself).
    const auto lastValidOf = [&](std::vector<double> from, std::vector<double> to) {
        std::pair<ompl::base::State *, double> out{exact.si->allocState(), -1.0};
        a[0] = from[0], a[1] = from[1], b[0] = to[0], b[1] = to[1];
        EXPECT_FALSE(validator->checkMotion(a.get(), b.get(), out));
        EXPECT_TRUE(exact.si->isValid(out.first)) << from[0] << "," << from[1] << " -> " << to[0] << "," << to[1];
        EXPECT_GE(out.second, 0.0);
        EXPECT_LE(out.second, 1.0);
        const double t = out.second;
        exact.si->freeState(out.first);
        return t;
    };
    EXPECT_GT(lastValidOf({8.0, 1.0}, {11.0, 1.0}), 0.0);
    EXPECT_GT(lastValidOf({1.5, 6.0 + 1e-13}, {2.5, 6.0 - 1e-13}), 0.0);
    EXPECT_EQ(lastValidOf({1.0, 1.0}, {std::nan(""), 1.0}), 0.0);
    std::pair<ompl::base::State *, double> nothing{nullptr, -1.0};  // only the fraction asked for
    a[0] = 4.0, a[1] = 1.0, b[0] = 6.0, b[1] = 1.0;
    EXPECT_FALSE(validator->checkMotion(a.get(), b.get(), nothing));
    EXPECT_NEAR(nothing.second, 0.5, 1e-8);
}

namespace
{
    /** \brief The plain test the checker's grid of boxes replaces: inside the bounds and outside every closed box,
     *  axis by axis. */
    bool plainIsValid(const BoxWorld &world, const double *x)
    {
        const std::size_t n = world.lower.size();
        for (std::size_t i = 0; i < n; ++i)
            if (!(x[i] >= world.lower[i] && x[i] <= world.upper[i]))
                return false;
        for (const Box &box : world.boxes)
        {
            std::size_t i = 0;
            while (i < n && x[i] >= box.lower[i] && x[i] <= box.upper[i])
                ++i;
            if (i == n)
                return false;
        }
        return true;
    }
}  // namespace

TEST(BoxWorld, GridOfBoxesAnswersAsThePlainTest)
{
    // From 4 boxes on the checker narrows them with a grid (64 cells per axis, bit sets of 64 boxes): the answers
    // must be the plain test's, on faces, on cell boundaries, for boxes that cover an axis, reach beyond the bounds,
    // miss them or are flat, and for more boxes than one word of bits holds.
    std::mt19937 rng(5u);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::size_t validWithGrid = 0u, invalidWithGrid = 0u;
    for (unsigned int n : {1u, 2u, 3u, 8u, 16u})
        for (std::size_t boxes : {0u, 3u, 4u, 30u, 64u, 65u, 130u})
        {
            BoxWorld world;
            for (unsigned int i = 0; i < n; ++i)
            {
                world.lower.push_back(-0.5 - unit(rng));
                world.upper.push_back(0.5 + unit(rng));
            }
            for (std::size_t b = 0; b < boxes; ++b)
            {
                Box box;
                for (unsigned int i = 0; i < n; ++i)
                {
                    const double extent = world.upper[i] - world.lower[i];
                    double lo = world.lower[i] + (1.4 * unit(rng) - 0.2) * extent;
                    double hi = lo + (b % 5u == 4u ? 0.0 : unit(rng) * extent);
                    if (b % 3u == 1u)  // faces on the grid's cell boundaries or the next double inside
                    {
                        lo = world.lower[i] + std::floor(unit(rng) * 65.0) * extent / 64.0;
                        hi = std::max(lo, world.lower[i] + std::floor(unit(rng) * 65.0) * extent / 64.0);
                        if (b % 2u == 0u)
                        {
                            lo = std::nextafter(lo, 1e300);
                            hi = std::max(lo, std::nextafter(hi, -1e300));
                        }
                    }
                    if (b % 7u == 3u && (i + b) % 2u == 0u)
                    {
                        lo = world.lower[i] - 1.0;
                        hi = world.upper[i] + 1.0;
                    }
                    box.lower.push_back(lo);
                    box.upper.push_back(hi);
                }
                world.boxes.push_back(box);
            }
            const BoxProblem problem =
                makeBoxProblem(world, std::vector<double>(n, 0.0), std::vector<double>(n, 0.0), 0.01);
            std::vector<double> x(n);
            std::size_t valid = 0u;
            for (int trial = 0; trial < 4000; ++trial)
            {
                // Half of the points inside a box on every axis but the ones redrawn below.
                if (boxes > 0u && trial % 2 == 0)
                {
                    const Box &box = world.boxes[static_cast<std::size_t>(unit(rng) * boxes) % boxes];
                    for (unsigned int i = 0; i < n; ++i)
                        x[i] = box.lower[i] + unit(rng) * (box.upper[i] - box.lower[i]);
                }
                for (unsigned int i = 0; i < n; ++i)
                {
                    if (trial % 2 == 0 && unit(rng) < 0.7)
                        continue;
                    const double extent = world.upper[i] - world.lower[i];
                    const int kind = static_cast<int>(unit(rng) * 6.0);
                    if (boxes > 0u && kind <= 1)
                    {
                        // On a face of a box, or the next double inside or outside it.
                        const Box &box = world.boxes[static_cast<std::size_t>(unit(rng) * boxes) % boxes];
                        const double face = kind == 0 ? box.lower[i] : box.upper[i];
                        const int step = static_cast<int>(unit(rng) * 3.0) - 1;
                        x[i] = step == 0 ? face : std::nextafter(face, step * 1e300);
                    }
                    else if (kind == 2)  // a cell boundary of the grid, or a bound
                        x[i] = world.lower[i] + std::floor(unit(rng) * 65.0) * extent / 64.0;
                    else
                        x[i] = world.lower[i] + (1.2 * unit(rng) - 0.1) * extent;
                }
                const bool expected = plainIsValid(world, x.data());
                valid += expected ? 1u : 0u;
                ASSERT_EQ(problem.checker->isValidPoint(x.data()), expected)
                    << "n " << n << ", boxes " << boxes << ", trial " << trial;
            }
            if (boxes >= 4u)
            {
                validWithGrid += valid;
                invalidWithGrid += 4000u - valid;
            }
        }
    // Both answers came from the grid, many times (in R^1 and R^2 many boxes leave no free space).
    EXPECT_GT(validWithGrid, 1000u);
    EXPECT_GT(invalidWithGrid, 1000u);
}
