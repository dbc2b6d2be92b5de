#include "lit/LookupTensor.h"

#include "NumberText.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <regex>
#include <sstream>

namespace lit
{
    namespace
    {
        /** \brief How an in-memory tensor's errors begin (load() replaces it by the file's name). */
        constexpr const char *valuePrefix = "tensor: ";

        /** \brief The grid index (i, j, k) of a flat index, as `lit tensors info` names it. */
        std::string gridIndex(const std::array<std::size_t, 3> &shape, std::size_t flat)
        {
            return "(" + std::to_string(flat / (shape[1] * shape[2])) + ", " + std::to_string(flat / shape[2] % shape[1]) +
                   ", " + std::to_string(flat % shape[2]) + ")";
        }

        /** \brief \e text with every byte outside printable ASCII written as \\xNN: the file's own bytes (a dtype,
         *  say) in a message that Python must decode as UTF-8 (a byte such as 0x88 made the error itself fail). */
        std::string printable(const std::string &text)
        {
            static const char *hex = "0123456789abcdef";
            std::string out;
            for (const unsigned char c : text)
            {
                if (c >= 0x20u && c < 0x7fu)
                    out += static_cast<char>(c);
                else
                    out += std::string("\\x") + hex[c >> 4u] + hex[c & 0xfu];
            }
            return out;
        }

        [[noreturn]] void fail(const std::string &path, const std::string &problem)
        {
            throw TensorError("tensor file '" + path + "': " + printable(problem));
        }

        /** \brief Index and weight of x in [0, 1] on a node-centred grid of n points. */
        void gridPosition(double x, std::size_t n, std::size_t &lower, double &weight)
        {
            const double scaled = std::clamp(std::isfinite(x) ? x : 0.0, 0.0, 1.0) * static_cast<double>(n - 1u);
            lower = std::min(static_cast<std::size_t>(scaled), n >= 2u ? n - 2u : 0u);
            weight = n >= 2u ? scaled - static_cast<double>(lower) : 0.0;
        }

        /** \brief The number of values of a grid of \e shape, or none when their bytes would not fit in a size_t (a
         *  product that wrapped around passed the size checks). */
        std::optional<std::size_t> valueCount(const std::array<std::size_t, 3> &shape)
        {
            std::size_t count = 1u;
            for (const std::size_t n : shape)
            {
                if (n != 0u && count > std::numeric_limits<std::size_t>::max() / sizeof(float) / n)
                    return std::nullopt;
                count *= n;
            }
            return count;
        }

        std::size_t nearestIndex(double x, std::size_t n)
        {
            const double scaled = std::clamp(std::isfinite(x) ? x : 0.0, 0.0, 1.0) * static_cast<double>(n - 1u);
            return std::min(static_cast<std::size_t>(std::floor(scaled + 0.5)), n - 1u);
        }
    }  // namespace

    LookupTensor::LookupTensor(std::array<std::size_t, 3> shape, std::vector<float> values)
      : shape_(shape), values_(std::move(values))
    {
        const std::optional<std::size_t> count = valueCount(shape_);
        if (shape_[0] == 0u || shape_[1] == 0u || shape_[2] == 0u || !count || values_.size() != *count)
            throw TensorError(std::string(valuePrefix) + "value count does not match the shape");
        // Lookups would interpolate a NaN into B or psi_K (load() adds the file's name).
        for (std::size_t i = 0; i < values_.size(); ++i)
            if (!std::isfinite(values_[i]))
                throw TensorError(std::string(valuePrefix) + "value " + detail::numberText(values_[i]) + " at index " +
                                  gridIndex(shape_, i) + " is not finite");
    }

    LookupTensor LookupTensor::load(const std::string &path, const TensorSpec &spec)
    {
        std::error_code ignored;
        if (std::filesystem::is_directory(path, ignored))  // opened, and read as "basic_string::_M_replace_aux"
            fail(path, "is a folder, not a tensor file");
        std::ifstream in(path, std::ios::binary);
        if (!in)
            fail(path, "cannot be opened");
        // In one read when the file's size is known (a byte at a time through istreambuf_iterator took about
        // 8 ms for a 101^3 tensor, twice per plan with the tensor policy); else (a pipe, say) as a stream.
        std::string bytes;
        in.seekg(0, std::ios::end);
        const std::streamoff size = in.tellg();
        if (size >= 0 && in.seekg(0, std::ios::beg))
        {
            bytes.resize(static_cast<std::size_t>(size));
            in.read(bytes.data(), size);
            bytes.resize(static_cast<std::size_t>(in.gcount()));
        }
        else
        {
            in.clear();
            in.seekg(0, std::ios::beg);
            bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
        }

        static const char magic[] = "\x93NUMPY";
        if (bytes.size() < 10u || bytes.compare(0, 6, magic, 6) != 0)
            fail(path, "bad magic: not an NPY file");
        const auto major = static_cast<unsigned char>(bytes[6]);
        const auto minor = static_cast<unsigned char>(bytes[7]);
        if (major != 1u || minor != 0u)
            fail(path, "unsupported NPY version " + std::to_string(major) + "." + std::to_string(minor) +
                           " (expected 1.0)");
        const std::size_t headerLength =
            static_cast<unsigned char>(bytes[8]) | (static_cast<std::size_t>(static_cast<unsigned char>(bytes[9])) << 8);
        if (bytes.size() < 10u + headerLength)
            fail(path, "truncated header");
        const std::string header = bytes.substr(10u, headerLength);
        // A Python dict literal, padded with spaces and ended by a newline (numpy refuses anything else).
        const std::size_t last = header.find_last_not_of(" \n");
        if (header.empty() || header.front() != '{' || last == std::string::npos || header[last] != '}')
            fail(path, "header is not a dict ('{...}')");

        std::smatch match;
        if (!std::regex_search(header, match, std::regex("'descr'\\s*:\\s*'([^']*)'")))
            fail(path, "header has no dtype ('descr')");
        if (match[1].str() != "<f4")
            fail(path, "dtype is '" + match[1].str() + "', expected '<f4' (little-endian float32)");
        if (!std::regex_search(header, match, std::regex("'fortran_order'\\s*:\\s*(True|False)")))
            fail(path, "header has no 'fortran_order'");
        if (match[1].str() != "False")
            fail(path, "Fortran order is not supported (expected C order)");
        if (!std::regex_search(header, match, std::regex("'shape'\\s*:\\s*\\(([^)]*)\\)")))
            fail(path, "header has no shape");

        std::vector<std::size_t> shape;
        {
            std::stringstream dims(match[1].str());
            std::string item;
            while (std::getline(dims, item, ','))
            {
                item.erase(std::remove_if(item.begin(), item.end(), ::isspace), item.end());
                if (item.empty())
                    continue;
                // Digits only, and few enough not to overflow (std::stoull would throw its own exception).
                if (item.size() > 9u ||
                    !std::all_of(item.begin(), item.end(), [](unsigned char c) { return std::isdigit(c) != 0; }))
                    fail(path, "shape entry '" + (item.size() > 20u ? item.substr(0, 20) + "..." : item) +
                                   "' is not a whole number below 10^9");
                shape.push_back(static_cast<std::size_t>(std::stoull(item)));
            }
        }
        auto shapeText = [](const auto &s) {
            std::string text = "(";
            for (std::size_t i = 0; i < s.size(); ++i)
                text += (i ? ", " : "") + std::to_string(s[i]);
            return text + ")";
        };
        if (shape.size() != 3u || shape[0] != spec.shape[0] || shape[1] != spec.shape[1] || shape[2] != spec.shape[2])
            fail(path, "shape " + shapeText(shape) + " does not match the sidecar's " + shapeText(spec.shape));

        const std::optional<std::size_t> counted = valueCount({shape[0], shape[1], shape[2]});
        if (!counted)
            fail(path, "shape " + shapeText(shape) + " holds more values than memory can");
        const std::size_t count = *counted;
        const std::size_t dataOffset = 10u + headerLength;
        if (bytes.size() - dataOffset != count * sizeof(float))
            fail(path, "data holds " + std::to_string(bytes.size() - dataOffset) + " bytes, expected " +
                           std::to_string(count * sizeof(float)));

        std::vector<float> values(count);
        std::memcpy(values.data(), bytes.data() + dataOffset, count * sizeof(float));  // x86-64: little-endian
        std::optional<LookupTensor> tensor;
        try
        {
            tensor.emplace(std::array<std::size_t, 3>{shape[0], shape[1], shape[2]}, std::move(values));  // finite
        }
        catch (const TensorError &error)
        {
            fail(path, std::string(error.what()).substr(std::strlen(valuePrefix)));
        }
        const std::vector<float> &stored = tensor->values_;
        for (std::size_t i = 0; i < count; ++i)
            if (stored[i] < spec.minValue - 1e-4 || stored[i] > spec.maxValue + 1e-4)
                fail(path, "value " + detail::numberText(stored[i]) + " at index " + gridIndex(tensor->shape_, i) +
                               " is out of range [" + detail::numberText(spec.minValue) + ", " +
                               detail::numberText(spec.maxValue) + "]");
        return std::move(*tensor);
    }

    double LookupTensor::nearest(double x, double y, double z) const
    {
        return at(nearestIndex(x, shape_[0]), nearestIndex(y, shape_[1]), nearestIndex(z, shape_[2]));
    }

    double LookupTensor::trilinear(double x, double y, double z) const
    {
        std::size_t i, j, k;
        double u, v, w;
        gridPosition(x, shape_[0], i, u);
        gridPosition(y, shape_[1], j, v);
        gridPosition(z, shape_[2], k, w);
        const std::size_t i1 = std::min(i + 1u, shape_[0] - 1u), j1 = std::min(j + 1u, shape_[1] - 1u),
                          k1 = std::min(k + 1u, shape_[2] - 1u);
        const double c00 = at(i, j, k) * (1 - w) + at(i, j, k1) * w;
        const double c01 = at(i, j1, k) * (1 - w) + at(i, j1, k1) * w;
        const double c10 = at(i1, j, k) * (1 - w) + at(i1, j, k1) * w;
        const double c11 = at(i1, j1, k) * (1 - w) + at(i1, j1, k1) * w;
        return (c00 * (1 - v) + c01 * v) * (1 - u) + (c10 * (1 - v) + c11 * v) * u;
    }
}  // namespace lit
