#include "Worlds.h"

#include <ompl/base/ScopedState.h>

#include <gtest/gtest.h>

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
