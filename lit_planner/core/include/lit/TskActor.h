#pragma once
/** \file TskActor.h
 *  \brief The learner's actor (fuzzification, Conv1d trunk, MLP, softmax, TSK defuzzification) as one compiled
 *  forward pass for a single state. The learner node answers every training decision with it: the same arithmetic
 *  in numpy costs about 35 µs of per-operation overhead, which sits on the planner's critical path. */

#include <Eigen/Dense>

#include <array>
#include <utility>
#include <vector>

namespace lit
{
    /** \brief z*(rho_global, rho_local, m) of fixed weights (a snapshot: the learner rebuilds it after each update).
     *
     *  The state is the 9-vector exp(-(f_i - c_j)^2 / (2 sigma^2)), index 3 i + j (feature i, centre j). The trunk is
     *  one affine map of it followed by ReLU (the learner folds its parallel same-padded convolutions into that
     *  matrix); then affine layers with ReLU between them; the last layer's outputs are rule logits, whose softmax
     *  weights the fixed consequents.
     *
     *  The affine maps run in single precision, as the torch actor they copy does: half the weight bytes of double, so
     *  a decision reads about 160 KB of weights instead of 330 KB (mostly from cache levels other processes have
     *  since used) and does twice the arithmetic per SIMD instruction. Memberships, softmax and TSK stay double. */
    class TskActor
    {
    public:
        using Layer = std::pair<Eigen::MatrixXd, Eigen::VectorXd>;

        /** \brief Checks every shape against its neighbours; throws std::invalid_argument naming the mismatch. */
        TskActor(std::array<double, 3> centres, double sigma, Layer trunk, std::vector<Layer> layers,
                 Eigen::VectorXd consequents);

        /** \brief The actor's output for one raw feature triple. */
        double operator()(double rhoGlobal, double rhoLocal, double measure) const;

    private:
        using FloatLayer = std::pair<Eigen::MatrixXf, Eigen::VectorXf>;

        std::array<double, 3> centres_;
        double scale_;
        FloatLayer trunk_;
        std::vector<FloatLayer> layers_;
        Eigen::VectorXd consequents_;
    };
}  // namespace lit
