#include "lit/TskActor.h"

#include "NumberText.h"

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

        std::pair<Eigen::MatrixXf, Eigen::VectorXf> single(const TskActor::Layer &layer)
        {
            return {layer.first.cast<float>(), layer.second.cast<float>()};
        }
    }  // namespace

    TskActor::TskActor(std::array<double, 3> centres, double sigma, Layer trunk, std::vector<Layer> layers,
                       Eigen::VectorXd consequents)
      : centres_(centres), consequents_(std::move(consequents))
    {
        if (!(std::isfinite(sigma) && sigma > 0.0))
            throw std::invalid_argument("sigma must be finite and positive, got " + detail::numberText(sigma));
        scale_ = -1.0 / (2.0 * sigma * sigma);
        checkLayer(trunk, 9, "trunk");
        Eigen::Index inputs = trunk.first.rows();
        for (std::size_t i = 0; i < layers.size(); ++i)
        {
            checkLayer(layers[i], inputs, "layer " + std::to_string(i));
            inputs = layers[i].first.rows();
        }
        if (inputs == 0)  // the softmax over no rule outputs: maxCoeff() of an empty vector
            throw std::invalid_argument("the last layer has no outputs: the TSK rules need at least one");
        if (consequents_.size() != inputs)
            throw std::invalid_argument("consequents: " + std::to_string(consequents_.size()) +
                                        " entries, expected one per rule output (" + std::to_string(inputs) + ")");
        trunk_ = single(trunk);
        layers_.reserve(layers.size());
        for (const Layer &layer : layers)
            layers_.push_back(single(layer));
    }

    double TskActor::operator()(double rhoGlobal, double rhoLocal, double measure) const
    {
        const double features[3] = {rhoGlobal, rhoLocal, measure};
        Eigen::VectorXf x(9);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
            {
                const double d = features[i] - centres_[static_cast<std::size_t>(j)];
                x(3 * i + j) = static_cast<float>(std::exp(d * d * scale_));
            }
        Eigen::VectorXf h = (trunk_.first * x + trunk_.second).cwiseMax(0.0f);
        for (std::size_t i = 0; i < layers_.size(); ++i)
        {
            h = layers_[i].first * h + layers_[i].second;
            if (i + 1 < layers_.size())
                h = h.cwiseMax(0.0f);
        }
        const Eigen::VectorXd logits = h.cast<double>();
        const Eigen::VectorXd w = (logits.array() - logits.maxCoeff()).exp().matrix();
        return w.dot(consequents_) / w.sum();
    }
}  // namespace lit
