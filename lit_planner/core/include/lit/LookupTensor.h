#pragma once
/** \file LookupTensor.h
 *  \brief Reader of the trained lookup tensors (NPY v1.0, little-endian float32, 3 axes over [0, 1]). */

#include <array>
#include <stdexcept>
#include <string>
#include <vector>

namespace lit
{
    /** \brief Raised for any defect of a tensor file; the message names the file and the problem. */
    class TensorError : public std::runtime_error
    {
    public:
        using std::runtime_error::runtime_error;
    };

    /** \brief How a lookup maps features to grid values. */
    enum class Interpolation
    {
        Nearest,
        Trilinear
    };

    /** \brief What the sidecar promises about the tensor; the reader checks the file against it. The JSON
     *  sidecar itself is parsed and schema-validated on the Python side (the core stays free of JSON). */
    struct TensorSpec
    {
        /** \brief Grid points per axis (node-centred over [0, 1]). */
        std::array<std::size_t, 3> shape{{101u, 101u, 101u}};
        /** \brief Inclusive range every value must lie in. */
        double minValue{0.0};
        double maxValue{0.0};
    };

    /** \brief A validated 3-D lookup tensor, O(1) lookups. */
    class LookupTensor
    {
    public:
        /** \brief Loads and validates \e path (magic, version, dtype, order, shape, size, finiteness, range). */
        static LookupTensor load(const std::string &path, const TensorSpec &spec);

        /** \brief Builds a tensor from values in C order (for tests and for in-memory policies). */
        LookupTensor(std::array<std::size_t, 3> shape, std::vector<float> values);

        /** \brief Value at the grid node nearest to (x, y, z); inputs are clamped to [0, 1]. */
        double nearest(double x, double y, double z) const;

        /** \brief Trilinear interpolation at (x, y, z); inputs are clamped to [0, 1]. */
        double trilinear(double x, double y, double z) const;

        /** \brief Lookup with the given interpolation. */
        double lookup(double x, double y, double z, Interpolation mode) const
        {
            return mode == Interpolation::Nearest ? nearest(x, y, z) : trilinear(x, y, z);
        }

        /** \brief The grid shape. */
        const std::array<std::size_t, 3> &shape() const
        {
            return shape_;
        }

        /** \brief Value at grid indices, each below its shape entry (not checked: the lookups' inner loop). */
        double at(std::size_t i, std::size_t j, std::size_t k) const
        {
            return values_[(i * shape_[1] + j) * shape_[2] + k];
        }

    private:
        std::array<std::size_t, 3> shape_;
        std::vector<float> values_;
    };
}  // namespace lit
