#include "Worlds.h"

#include <ompl/base/ScopedState.h>

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

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
