#include "lit/ParameterPolicy.h"

#include "NumberText.h"

#include <ompl/util/Console.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <stdexcept>
#include <string>

namespace lit
{
    const char *toString(DecisionKind kind)
    {
        return kind == DecisionKind::BatchSize ? "B" : "psi_K";
    }

    std::optional<int> clampBatchSize(double value)
    {
        if (!std::isfinite(value))
            return std::nullopt;
        const double rounded = std::round(value);  // half away from zero
        return static_cast<int>(std::clamp(rounded, static_cast<double>(ParameterLimits::minBatchSize),
                                           static_cast<double>(ParameterLimits::maxBatchSize)));
    }

    std::optional<double> clampNeighbourFactor(double value)
    {
        if (!std::isfinite(value))
            return std::nullopt;
        return std::clamp(value, ParameterLimits::minNeighbourFactor, ParameterLimits::maxNeighbourFactor);
    }

    FixedPolicy::FixedPolicy(int batchSize, double neighbourFactor)
      : batchSize_(batchSize), neighbourFactor_(neighbourFactor)
    {
        // B = 0 or less became B = 1 and the factor was never used: both were accepted without a word.
        if (batchSize < 1)
            throw std::invalid_argument("FixedPolicy: the batch size must be at least 1, got " +
                                        std::to_string(batchSize));
        if (!(std::isfinite(neighbourFactor) && neighbourFactor > 0.0))
            throw std::invalid_argument("FixedPolicy: the neighbour factor must be a positive number, got " +
                                        detail::numberText(neighbourFactor));
    }

    double FixedPolicy::decide(const DecisionContext &context)
    {
        return context.kind == DecisionKind::BatchSize ? static_cast<double>(batchSize_) : neighbourFactor_;
    }

    double FitPolicy::batchSize(double xi, unsigned int n, double minBatch, double maxBatch)
    {
        if (n == 0u)  // Lambda = (m_max + m_min) / 0: infinite, and the rule NaN
            throw std::invalid_argument("FitPolicy: the rule needs a dimension of at least 1, got 0");
        const double sigmoid = 1.0 / (1.0 + std::exp(-10.0 * (xi - 0.5)));
        const double lambda = (maxBatch + minBatch) / static_cast<double>(n);
        const double psi = std::log1p(lambda * sigmoid) / std::log1p(lambda);
        return minBatch + (maxBatch - minBatch) * psi;
    }

    double FitPolicy::decide(const DecisionContext &context)
    {
        if (context.kind == DecisionKind::NeighbourFactor)
            return M_E;
        if (!context.hasSolution)
            return maxBatch_;
        const double reference = context.firstSolutionMeasure;
        const double xi = reference > 0.0 ? context.informedMeasure / reference : 1.0;
        return std::round(batchSize(xi, context.dimension, minBatch_, maxBatch_));
    }

    TensorPolicy::TensorPolicy(std::shared_ptr<const LookupTensor> batchTensor,
                               std::shared_ptr<const LookupTensor> neighbourTensor, Interpolation interpolation,
                               unsigned int decisionInterval)
      : batchTensor_(std::move(batchTensor))
      , neighbourTensor_(std::move(neighbourTensor))
      , interpolation_(interpolation)
      , decisionInterval_(decisionInterval)
    {
    }

    double TensorPolicy::decide(const DecisionContext &context)
    {
        const Features &f = context.features;
        if (context.kind == DecisionKind::BatchSize)
        {
            if (!batchTensor_)
                return 100.0;
            return *clampBatchSize(batchTensor_->lookup(f.rhoGlobal, f.rhoLocalB, f.measure, interpolation_));
        }
        if (!neighbourTensor_)
            return M_E;
        return *clampNeighbourFactor(neighbourTensor_->lookup(f.rhoGlobal, f.rhoLocalK, f.measure, interpolation_));
    }

    double ExternalPolicy::decide(const DecisionContext &context)
    {
        const double fallback = context.kind == DecisionKind::BatchSize ? 100.0 : M_E;
        double answer = fallback;
        try
        {
            answer = callback_(context);
        }
        catch (const PolicyAbort &)
        {
            throw;  // ends the solve
        }
        catch (const std::exception &e)
        {
            // The first failure of each kind is logged, later ones only counted (failures()): hundreds of lines per
            // plan otherwise.
            ++failures_;
            if (!warnedRaised_.exchange(true))
                OMPL_WARN("LITstar: external policy raised '%s'; using the fixed value for %s (later exceptions of "
                          "this policy are counted, not logged)",
                          e.what(), toString(context.kind));
            return fallback;
        }
        if (context.kind == DecisionKind::BatchSize)
        {
            if (auto b = clampBatchSize(answer))
                return *b;
        }
        else if (auto psi = clampNeighbourFactor(answer))
            return *psi;
        ++failures_;
        if (!warnedUnusable_.exchange(true))
            OMPL_WARN("LITstar: external policy answered NaN/inf for %s; using the fixed value (later such answers of "
                      "this policy are counted, not logged)",
                      toString(context.kind));
        return fallback;
    }
}  // namespace lit
