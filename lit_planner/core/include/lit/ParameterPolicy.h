#pragma once
/** \file ParameterPolicy.h
 *  \brief Where LIT*'s batch size B and neighbour factor psi_K come from: fixed (EIT*), FIT*'s rule, the
 *  trained lookup tensors, or an external callable (training). */

#include "lit/LookupTensor.h"

#include <atomic>
#include <cmath>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

namespace lit
{
    /** \brief Which parameter a decision sets. */
    enum class DecisionKind
    {
        BatchSize,
        NeighbourFactor
    };

    /** \brief Name of a decision kind as used in reports ("B" or "psi_K"). */
    const char *toString(DecisionKind kind);

    /** \brief The observation features of the paper (each in [0, 1]). */
    struct Features
    {
        /** \brief |X_invalid| / (|X_valid| + |X_invalid|). */
        double rhoGlobal{0.0};
        /** \brief Mean invalid ratio within r of the states on the current best path (rho_global without one). */
        double rhoLocalB{0.0};
        /** \brief Invalid ratio within r of the state being expanded (rho_global when empty). */
        double rhoLocalK{0.0};
        /** \brief (lambda(X_f) / lambda(X))^(1/n); 1 before the first solution. */
        double measure{1.0};
    };

    /** \brief Everything a policy may look at when it decides. */
    struct DecisionContext
    {
        DecisionKind kind{DecisionKind::BatchSize};
        Features features;
        /** \brief Dimension of the state space. */
        unsigned int dimension{0u};
        /** \brief Whether a solution exists, its cost, and the number of improvements so far. */
        bool hasSolution{false};
        double cost{0.0};
        std::size_t improvements{0u};
        /** \brief Number of states on the current best path (0 without one). */
        std::size_t pathStates{0u};
        /** \brief Planner time (s), external-policy time excluded. */
        double planningTime{0.0};
        /** \brief Absolute measure of the informed set and of the space. */
        double informedMeasure{0.0};
        double spaceMeasure{0.0};
        /** \brief The informed set's measure when this problem's first solution was found (0 before it). */
        double firstSolutionMeasure{0.0};
        /** \brief Straight-line start-goal distance. */
        double minimumCost{0.0};
        /** \brief Number of expansions so far (K decisions) / batches so far (B decisions). */
        std::size_t expansions{0u};
        std::size_t batches{0u};
        /** \brief States checked so far (samples and edge points): a deterministic effort clock. */
        std::size_t checks{0u};
    };

    /** \brief The paper's range of B and psi_K, to which the tensor and external policies clamp their answers.
     *  LIT* itself takes any B >= 1 and psi_K > 0 from a policy: the fixed policy's psi_K = e is below 3, and
     *  FIT*'s rule ranges over 1...199. */
    struct ParameterLimits
    {
        static constexpr int minBatchSize = 20;
        static constexpr int maxBatchSize = 200;
        static constexpr double minNeighbourFactor = 3.0;
        static constexpr double maxNeighbourFactor = 15.0;
    };

    /** \brief Rounds half away from zero and clamps to [20, 200]; NaN or +-inf gives std::nullopt. */
    std::optional<int> clampBatchSize(double value);

    /** \brief Clamps to [3, 15]; NaN or +-inf gives std::nullopt. */
    std::optional<double> clampNeighbourFactor(double value);

    /** \brief Source of B and psi_K.
     *
     *  The planner passes everything about its problem in the DecisionContext, so the built-in policies keep no
     *  per-problem state: one policy may serve several planners, also solving at the same time (an external
     *  policy's callable must then be thread-safe itself). */
    class ParameterPolicy
    {
    public:
        virtual ~ParameterPolicy() = default;

        /** \brief Short name used in reports: "fixed", "fit", "tensor", "external". */
        virtual std::string name() const = 0;

        /** \brief Whether decide() looks at the features (the planner skips computing them otherwise). */
        virtual bool needsFeatures() const
        {
            return true;
        }

        /** \brief Batch size before the first solution (B is decided at solution improvements). */
        virtual int initialBatchSize() const
        {
            return 100;
        }

        /** \brief psi_K until the first decision, and throughout when decidesNeighbourFactor() is false. */
        virtual double initialNeighbourFactor() const
        {
            return M_E;
        }

        /** \brief Whether psi_K is decided at expansions (false: initialNeighbourFactor() throughout). */
        virtual bool decidesNeighbourFactor() const
        {
            return true;
        }

        /** \brief The value for \e context.kind: B (an integer) or psi_K. */
        virtual double decide(const DecisionContext &context) = 0;

        /** \brief Whether the planner's clock is paused while decide() runs (external answers). */
        virtual bool pausesClock() const
        {
            return false;
        }

    };

    using ParameterPolicyPtr = std::shared_ptr<ParameterPolicy>;

    /** \brief B = 100, psi_K = e: the EIT* baseline. */
    class FixedPolicy : public ParameterPolicy
    {
    public:
        /** \throws std::invalid_argument for a batch size below 1 or a factor that is not a positive number. */
        explicit FixedPolicy(int batchSize = 100, double neighbourFactor = M_E);
        std::string name() const override
        {
            return "fixed";
        }
        bool needsFeatures() const override
        {
            return false;
        }
        int initialBatchSize() const override
        {
            return batchSize_;
        }
        double initialNeighbourFactor() const override
        {
            return neighbourFactor_;
        }
        bool decidesNeighbourFactor() const override
        {
            return false;
        }
        double decide(const DecisionContext &context) override;

    private:
        int batchSize_;
        double neighbourFactor_;
    };

    /** \brief FIT*'s sigmoid-log batch rule (Zhang et al., IROS 2024) on the true n-D informed measure;
     *  psi_K = e. B = m_max before the first solution; the reference measure is the problem's at its first
     *  solution (DecisionContext::firstSolutionMeasure). */
    class FitPolicy : public ParameterPolicy
    {
    public:
        std::string name() const override
        {
            return "fit";
        }
        bool needsFeatures() const override
        {
            return false;
        }
        int initialBatchSize() const override
        {
            return static_cast<int>(maxBatch_);
        }
        bool decidesNeighbourFactor() const override
        {
            return false;
        }
        double decide(const DecisionContext &context) override;

        /** \brief The rule itself: B for measure ratio xi = lambda(now) / lambda(first solution) in R^n.
         *  \throws std::invalid_argument for n = 0. */
        static double batchSize(double xi, unsigned int n, double minBatch = 1.0, double maxBatch = 199.0);

    private:
        double minBatch_{1.0};
        double maxBatch_{199.0};
    };

    /** \brief O(1) lookups in the trained B and psi_K tensors (axes rho_global, rho_local, m). A missing
     *  tensor falls back to the fixed value of that parameter. */
    class TensorPolicy : public ParameterPolicy
    {
    public:
        /** \brief \e decisionInterval: the expansions per psi_K decision the psi_K tensor was trained with
         *  (0: not known). The policy does not apply it itself; lit_planner.planning.plan sets the planner's
         *  decision_interval to it unless the caller gives one, so the tensor is used as it was trained. */
        TensorPolicy(std::shared_ptr<const LookupTensor> batchTensor,
                     std::shared_ptr<const LookupTensor> neighbourTensor, Interpolation interpolation,
                     unsigned int decisionInterval = 0u);
        std::string name() const override
        {
            return "tensor";
        }
        /** \brief The top of the B range (200) with a B tensor, as FIT* starts at m_max (the policy was
         *  trained that way); 100 (the fixed value) without one. */
        int initialBatchSize() const override
        {
            return batchTensor_ ? ParameterLimits::maxBatchSize : 100;
        }
        bool decidesNeighbourFactor() const override
        {
            return static_cast<bool>(neighbourTensor_);
        }
        double decide(const DecisionContext &context) override;
        /** \brief The psi_K tensor's training decision interval (0: not known). */
        unsigned int decisionInterval() const
        {
            return decisionInterval_;
        }
        /** \brief How lookups blend the grid's nodes. */
        Interpolation interpolation() const
        {
            return interpolation_;
        }

    private:
        std::shared_ptr<const LookupTensor> batchTensor_;
        std::shared_ptr<const LookupTensor> neighbourTensor_;
        Interpolation interpolation_;
        unsigned int decisionInterval_;
    };

    /** \brief Thrown by an external policy's callback to end the solve rather than fall back to a fixed value:
     *  the Python bindings throw it for KeyboardInterrupt and SystemExit (Ctrl-C during a solve was taken for a
     *  failed answer, and the solve planned on to its budget). */
    class PolicyAbort : public std::runtime_error
    {
    public:
        using std::runtime_error::runtime_error;
    };

    /** \brief Delegates to a callable (the learner in training). Out-of-range answers are clamped; a NaN
     *  or infinite answer or an exception falls back to the fixed value and is counted. The planner pauses its clock
     *  while the callable runs. */
    class ExternalPolicy : public ParameterPolicy
    {
    public:
        using Callback = std::function<double(const DecisionContext &)>;
        explicit ExternalPolicy(Callback callback, bool decidesNeighbourFactor = true)
          : callback_(std::move(callback)), decidesNeighbourFactor_(decidesNeighbourFactor)
        {
        }
        std::string name() const override
        {
            return "external";
        }
        bool decidesNeighbourFactor() const override
        {
            return decidesNeighbourFactor_;
        }
        bool pausesClock() const override
        {
            return true;
        }
        /** \brief The top of the B range (200), like the tensor policy it trains. */
        int initialBatchSize() const override
        {
            return ParameterLimits::maxBatchSize;
        }
        double decide(const DecisionContext &context) override;

        /** \brief Answers that were unusable (NaN, +-inf or a throwing callable). The first of each kind is logged. */
        std::size_t failures() const
        {
            return failures_;
        }

    private:
        Callback callback_;
        bool decidesNeighbourFactor_;
        std::atomic<std::size_t> failures_{0u};
        /** \brief Whether an exception, and an answer that is not a number, were logged (once each). */
        std::atomic<bool> warnedRaised_{false};
        std::atomic<bool> warnedUnusable_{false};
    };
}  // namespace lit
