#include "lit/TskActor.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace lit
{
    namespace
    {
        void checkLayer(const TskActor::Layer &layer, Eigen::Index inputs, const std::string &name)
        {
            if (layer.first.cols() != inputs)
                throw std::invalid_argument(name + ": weight has " + std::to_string(layer.first.cols()) +
                                            " columns, expected " + std::to_string(inputs) + " inputs");
            if (layer.second.size() != layer.first.rows())
                throw std::invalid_argument(name + ": bias has " + std::to_string(layer.second.size()) +
                                            " entries, expected " + std::to_string(layer.first.rows()));
        }
    }  // namespace

    TskActor::TskActor(std::array<double, 3> centres, double sigma, Layer trunk, std::vector<Layer> layers,
                       Eigen::VectorXd consequents)
      : centres_(centres)
      , trunk_(std::move(trunk))
      , layers_(std::move(layers))
      , consequents_(std::move(consequents))
    {
        if (!(std::isfinite(sigma) && sigma > 0.0))
            throw std::invalid_argument("sigma must be finite and positive, got " + std::to_string(sigma));
        scale_ = -1.0 / (2.0 * sigma * sigma);
        checkLayer(trunk_, 9, "trunk");
        Eigen::Index inputs = trunk_.first.rows();
        for (std::size_t i = 0; i < layers_.size(); ++i)
        {
            checkLayer(layers_[i], inputs, "layer " + std::to_string(i));
            inputs = layers_[i].first.rows();
        }
        if (consequents_.size() != inputs)
            throw std::invalid_argument("consequents: " + std::to_string(consequents_.size()) +
                                        " entries, expected one per rule output (" + std::to_string(inputs) + ")");
    }

    double TskActor::operator()(double rhoGlobal, double rhoLocal, double measure) const
    {
        const double features[3] = {rhoGlobal, rhoLocal, measure};
        Eigen::VectorXd x(9);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
            {
                const double d = features[i] - centres_[static_cast<std::size_t>(j)];
                x(3 * i + j) = std::exp(d * d * scale_);
            }
        Eigen::VectorXd h = (trunk_.first * x + trunk_.second).cwiseMax(0.0);
        for (std::size_t i = 0; i < layers_.size(); ++i)
        {
            h = layers_[i].first * h + layers_[i].second;
            if (i + 1 < layers_.size())
                h = h.cwiseMax(0.0);
        }
        const Eigen::VectorXd w = (h.array() - h.maxCoeff()).exp().matrix();
        return w.dot(consequents_) / w.sum();
    }
}  // namespace lit
