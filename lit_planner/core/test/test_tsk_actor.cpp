#include "Worlds.h"
#include "lit/TskActor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

using namespace lit;

namespace
{
    /** \brief A 9 -> 2 -> 3 actor small enough to evaluate by hand. */
    TskActor smallActor()
    {
        Eigen::MatrixXd trunkWeight = Eigen::MatrixXd::Zero(2, 9);
        trunkWeight(0, 0) = 1.0;   // membership of rho_global in the first set (centre 0)
        trunkWeight(1, 8) = -1.0;  // minus membership of m in the last set: ReLU makes it 0
        Eigen::VectorXd trunkBias(2);
        trunkBias << 0.5, 0.25;
        Eigen::MatrixXd weight(3, 2);
        weight << 1.0, 0.0, 0.0, 1.0, 0.0, 0.0;
        Eigen::VectorXd bias = Eigen::VectorXd::Zero(3);
        Eigen::VectorXd consequents(3);
        consequents << 10.0, 20.0, 30.0;
        return TskActor({0.0, 0.5, 1.0}, 0.5, {trunkWeight, trunkBias}, {{weight, bias}}, consequents);
    }
}  // namespace

TEST(TskActor, ComputesTheTskOutputByHand)
{
    const TskActor actor = smallActor();
    const double g = 0.3, m = 1.0;
    const double membership = std::exp(-(g * g) / (2.0 * 0.25));
    const double h0 = membership + 0.5;
    const double h1 = std::max(0.0, -std::exp(-((m - 1.0) * (m - 1.0)) / (2.0 * 0.25)) + 0.25);  // 0
    const double w0 = std::exp(h0), w1 = std::exp(h1), w2 = std::exp(0.0);
    const double expected = (10.0 * w0 + 20.0 * w1 + 30.0 * w2) / (w0 + w1 + w2);
    EXPECT_NEAR(actor(g, 0.7, m), expected, 1e-5);  // single-precision affine maps
}

TEST(TskActor, RejectsShapesThatDoNotChain)
{
    using test::throwsWith;
    const Eigen::VectorXd consequents = Eigen::VectorXd::Ones(3);
    const TskActor::Layer trunk{Eigen::MatrixXd::Zero(4, 9), Eigen::VectorXd::Zero(4)};
    const TskActor::Layer rules{Eigen::MatrixXd::Zero(3, 4), Eigen::VectorXd::Zero(3)};
    EXPECT_TRUE(throwsWith<std::invalid_argument>(
        [&] {
            TskActor({0.0, 0.5, 1.0}, 0.2, {Eigen::MatrixXd::Zero(4, 8), Eigen::VectorXd::Zero(4)}, {rules},
                     consequents);
        },
        "trunk: weight has 8 columns, expected 9 inputs"));
    EXPECT_TRUE(throwsWith<std::invalid_argument>(
        [&] {
            TskActor({0.0, 0.5, 1.0}, 0.2, trunk, {{Eigen::MatrixXd::Zero(3, 5), Eigen::VectorXd::Zero(3)}},
                     consequents);
        },
        "layer 0: weight has 5 columns, expected 4 inputs"));
    EXPECT_TRUE(throwsWith<std::invalid_argument>(
        [&] {
            TskActor({0.0, 0.5, 1.0}, 0.2, trunk, {{Eigen::MatrixXd::Zero(2, 4), Eigen::VectorXd::Zero(2)}},
                     consequents);
        },
        "consequents: 3 entries, expected one per rule output (2)"));
    EXPECT_TRUE(throwsWith<std::invalid_argument>(
        [&] { TskActor({0.0, 0.5, 1.0}, std::nan(""), trunk, {rules}, consequents); },
        "sigma must be finite and positive"));
    // No rule outputs: taken, and the softmax then read the maximum of an empty vector (a crash).
    EXPECT_TRUE(throwsWith<std::invalid_argument>(
        [&] {
            TskActor({0.0, 0.5, 1.0}, 1.0, {Eigen::MatrixXd::Zero(0, 9), Eigen::VectorXd::Zero(0)}, {},
                     Eigen::VectorXd::Zero(0));
        },
        "the last layer has no outputs"));
}
