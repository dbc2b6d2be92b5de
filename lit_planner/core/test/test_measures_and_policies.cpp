#include "lit/InformedMeasure.h"
#include "lit/ParameterPolicy.h"

#include <gtest/gtest.h>
#include <ompl/util/Console.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

using namespace lit;

TEST(InformedMeasure, UnitBallClosedForms)
{
    EXPECT_NEAR(unitBallMeasure(1), 2.0, 1e-12);
    EXPECT_NEAR(unitBallMeasure(2), M_PI, 1e-12);
    EXPECT_NEAR(unitBallMeasure(3), 4.0 / 3.0 * M_PI, 1e-12);
    EXPECT_NEAR(unitBallMeasure(4), M_PI * M_PI / 2.0, 1e-12);
}

TEST(InformedMeasure, ProlateHyperspheroidClosedForms)
{
    // Ellipse with foci distance 0.6 and cost 1.0: semi-axes a = 0.5, b = sqrt(1 - 0.36) / 2 = 0.4.
    EXPECT_NEAR(informedMeasure(2, 1.0, 0.6, 100.0), M_PI * 0.5 * 0.4, 1e-12);
    // Prolate spheroid in R^3: 4/3 pi a b^2.
    EXPECT_NEAR(informedMeasure(3, 1.0, 0.6, 100.0), 4.0 / 3.0 * M_PI * 0.5 * 0.4 * 0.4, 1e-12);
    // Capped at the space measure, infinite cost is the whole space, the straight line has measure 0.
    EXPECT_DOUBLE_EQ(informedMeasure(2, 10.0, 0.6, 1.0), 1.0);
    EXPECT_DOUBLE_EQ(informedMeasure(2, INFINITY, 0.6, 1.0), 1.0);
    EXPECT_DOUBLE_EQ(informedMeasure(2, 0.6, 0.6, 1.0), 0.0);
    // R^16 stays finite and positive right after a good solution (about 1e-8 of the space).
    const double m16 = informedMeasure(16, 0.45, 0.4236, 1.0);
    EXPECT_GT(m16, 0.0);
    EXPECT_LT(m16, 1e-6);
    EXPECT_NEAR(measureFeature(16, m16, 1.0), std::pow(m16, 1.0 / 16.0), 1e-12);
    EXPECT_DOUBLE_EQ(measureFeature(4, 1.0, 1.0), 1.0);
}

TEST(FitPolicy, SigmoidLogRuleValues)
{
    // Hand-computed: n = 8, Lambda = 200 / 8 = 25.
    EXPECT_NEAR(FitPolicy::batchSize(1.0, 8), 198.608, 1e-2);
    EXPECT_NEAR(FitPolicy::batchSize(0.5, 8), 159.171, 1e-2);
    EXPECT_NEAR(FitPolicy::batchSize(0.0, 8), 10.403, 1e-2);
    EXPECT_THROW(FitPolicy::batchSize(0.5, 0), std::invalid_argument);  // was NaN
    // Lambda is a real division: n = 16 gives 12.5 (not 12).
    const double o = 1.0 / (1.0 + std::exp(-10.0 * (0.3 - 0.5)));
    EXPECT_NEAR(FitPolicy::batchSize(0.3, 16), 1.0 + 198.0 * std::log1p(12.5 * o) / std::log1p(12.5), 1e-9);

    FitPolicy policy;
    DecisionContext context;
    context.kind = DecisionKind::BatchSize;
    context.dimension = 8;
    EXPECT_DOUBLE_EQ(policy.decide(context), 199.0);  // before the first solution
    context.hasSolution = true;
    context.informedMeasure = 0.2;
    context.firstSolutionMeasure = 0.2;  // reference: the first solution's measure, from the planner
    EXPECT_DOUBLE_EQ(policy.decide(context), std::round(FitPolicy::batchSize(1.0, 8)));
    context.informedMeasure = 0.1;
    EXPECT_DOUBLE_EQ(policy.decide(context), std::round(FitPolicy::batchSize(0.5, 8)));
    DecisionContext other = context;  // another problem (another planner) asking the same policy meanwhile
    other.firstSolutionMeasure = 0.1;
    EXPECT_DOUBLE_EQ(policy.decide(other), std::round(FitPolicy::batchSize(1.0, 8)));
    EXPECT_DOUBLE_EQ(policy.decide(context), std::round(FitPolicy::batchSize(0.5, 8)));
    context.kind = DecisionKind::NeighbourFactor;
    EXPECT_DOUBLE_EQ(policy.decide(context), M_E);
}

TEST(Policies, FixedAndClamping)
{
    FixedPolicy fixed;
    DecisionContext context;
    EXPECT_EQ(fixed.initialBatchSize(), 100);
    EXPECT_DOUBLE_EQ(fixed.decide(context), 100.0);
    context.kind = DecisionKind::NeighbourFactor;
    EXPECT_DOUBLE_EQ(fixed.decide(context), M_E);

    EXPECT_EQ(*clampBatchSize(20.5), 21);  // half away from zero
    EXPECT_EQ(*clampBatchSize(3.0), 20);
    EXPECT_EQ(*clampBatchSize(1e9), 200);
    EXPECT_FALSE(clampBatchSize(NAN).has_value());
    EXPECT_DOUBLE_EQ(*clampNeighbourFactor(1.0), 3.0);
    EXPECT_DOUBLE_EQ(*clampNeighbourFactor(99.0), 15.0);
    EXPECT_FALSE(clampNeighbourFactor(INFINITY).has_value());
}

TEST(Policies, ExternalClampsAndFallsBack)
{
    int calls = 0;
    ExternalPolicy policy([&calls](const DecisionContext &context) -> double {
        ++calls;
        if (context.expansions == 1u)
            return NAN;
        if (context.expansions == 2u)
            throw std::runtime_error("learner gone");
        return context.kind == DecisionKind::BatchSize ? 1000.4 : 7.5;
    });
    EXPECT_TRUE(policy.pausesClock());
    DecisionContext context;
    EXPECT_DOUBLE_EQ(policy.decide(context), 200.0);
    context.kind = DecisionKind::NeighbourFactor;
    EXPECT_DOUBLE_EQ(policy.decide(context), 7.5);
    struct Warnings : ompl::msg::OutputHandler
    {
        std::vector<std::string> lines;
        void log(const std::string &text, ompl::msg::LogLevel level, const char *, int) override
        {
            if (level >= ompl::msg::LOG_WARN)
                lines.push_back(text);
        }
    } warnings;
    ompl::msg::useOutputHandler(&warnings);
    for (int round = 0; round < 3; ++round)
    {
        context.expansions = 1u;
        context.kind = DecisionKind::NeighbourFactor;
        EXPECT_DOUBLE_EQ(policy.decide(context), M_E);
        context.expansions = 2u;
        context.kind = DecisionKind::BatchSize;
        EXPECT_DOUBLE_EQ(policy.decide(context), 100.0);
    }
    ompl::msg::restorePreviousOutputHandler();
    EXPECT_EQ(policy.failures(), 6u);
    EXPECT_EQ(calls, 8);
    // The first failure of each kind is logged, the others counted: a plan's hundreds of failed answers gave as
    // many lines.
    ASSERT_EQ(warnings.lines.size(), 2u);
    EXPECT_NE(warnings.lines[0].find("answered NaN/inf for psi_K"), std::string::npos) << warnings.lines[0];
    EXPECT_NE(warnings.lines[1].find("raised 'learner gone'; using the fixed value for B"), std::string::npos)
        << warnings.lines[1];
}
