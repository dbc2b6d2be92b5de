#include "lit/LookupTensor.h"
#include "lit/ParameterPolicy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

using namespace lit;

namespace
{
    constexpr std::size_t N = 101u;

    double affine(double x, double y, double z)
    {
        return 20.0 + 100.0 * x + 50.0 * y + 25.0 * z;
    }

    std::vector<float> affineValues()
    {
        std::vector<float> values(N * N * N);
        for (std::size_t i = 0; i < N; ++i)
            for (std::size_t j = 0; j < N; ++j)
                for (std::size_t k = 0; k < N; ++k)
                    values[(i * N + j) * N + k] = static_cast<float>(affine(i / 100.0, j / 100.0, k / 100.0));
        return values;
    }

    /** \brief Writes an NPY v1.0 file with an arbitrary header dictionary and payload. */
    std::string writeNpy(const std::string &name, const std::string &dict, const std::string &payload,
                         const std::string &magic = "\x93NUMPY", char major = 1)
    {
        const std::string path = ::testing::TempDir() + name;
        std::string header = dict;
        while ((10u + header.size() + 1u) % 64u != 0u)
            header += ' ';
        header += '\n';
        std::ofstream out(path, std::ios::binary);
        out.write(magic.data(), 6);
        out.put(major);
        out.put(0);
        out.put(static_cast<char>(header.size() & 0xff));
        out.put(static_cast<char>(header.size() >> 8));
        out << header << payload;
        return path;
    }

    std::string payload(const std::vector<float> &values)
    {
        return std::string(reinterpret_cast<const char *>(values.data()), values.size() * sizeof(float));
    }

    const std::string goodDict = "{'descr': '<f4', 'fortran_order': False, 'shape': (101, 101, 101), }";
    const TensorSpec spec{{N, N, N}, 20.0, 200.0};

    std::string loadError(const std::string &path)
    {
        try
        {
            LookupTensor::load(path, spec);
        }
        catch (const TensorError &e)
        {
            return e.what();
        }
        return "";
    }
}  // namespace

TEST(LookupTensor, AffineTensorIsReproducedExactlyByTrilinear)
{
    const auto path = writeNpy("affine.npy", goodDict, payload(affineValues()));
    const LookupTensor tensor = LookupTensor::load(path, spec);
    const double points[][3] = {{0.0, 0.0, 0.0}, {1.0, 1.0, 1.0}, {0.123, 0.456, 0.789}, {0.5, 0.25, 0.999}, {0.005, 0.995, 0.3333}};
    for (const auto &p : points)
        EXPECT_NEAR(tensor.trilinear(p[0], p[1], p[2]), affine(p[0], p[1], p[2]), 1e-4);
    // Nearest rounds to the closest node (half up) and clamps to [0, 1].
    EXPECT_NEAR(tensor.nearest(0.123, 0.456, 0.789), affine(0.12, 0.46, 0.79), 1e-4);
    EXPECT_NEAR(tensor.nearest(0.005, 0.0, 0.0), affine(0.01, 0.0, 0.0), 1e-4);
    EXPECT_NEAR(tensor.nearest(-3.0, 7.0, 0.5), affine(0.0, 1.0, 0.5), 1e-4);
    EXPECT_NEAR(tensor.trilinear(-3.0, 7.0, 0.5), affine(0.0, 1.0, 0.5), 1e-4);
}

TEST(LookupTensor, RejectsEachDefectWithItsOwnMessage)
{
    const auto good = affineValues();
    EXPECT_NE(loadError(::testing::TempDir() + "does-not-exist.npy").find("cannot be opened"), std::string::npos);
    EXPECT_NE(loadError(writeNpy("magic.npy", goodDict, payload(good), "\x93NUMPZ")).find("bad magic"), std::string::npos);
    EXPECT_NE(loadError(writeNpy("version.npy", goodDict, payload(good), "\x93NUMPY", 3)).find("NPY version"), std::string::npos);
    EXPECT_NE(loadError(writeNpy("dtype.npy", "{'descr': '<f8', 'fortran_order': False, 'shape': (101, 101, 101), }", payload(good)))
                  .find("dtype is '<f8'"), std::string::npos);
    // The file's own bytes are escaped: Python decodes the message as UTF-8, and 0x88 failed that.
    EXPECT_NE(loadError(writeNpy("bytes.npy", "{'descr': '\x88" "f4', 'fortran_order': False, 'shape': (101, 101, 101), }",
                                 payload(good)))
                  .find("dtype is '\\x88f4'"), std::string::npos);
    EXPECT_NE(loadError(writeNpy("order.npy", "{'descr': '<f4', 'fortran_order': True, 'shape': (101, 101, 101), }", payload(good)))
                  .find("Fortran order"), std::string::npos);
    EXPECT_NE(loadError(writeNpy("shape.npy", "{'descr': '<f4', 'fortran_order': False, 'shape': (101, 101), }", payload(good)))
                  .find("shape (101, 101) does not match"), std::string::npos);
    EXPECT_NE(loadError(writeNpy("short.npy", goodDict, payload(good).substr(0, 1000))).find("data holds 1000 bytes"),
              std::string::npos);
    auto withNan = good;
    withNan[12345] = NAN;
    EXPECT_NE(loadError(writeNpy("nan.npy", goodDict, payload(withNan))).find("value nan at index (1, 21, 23) is not finite"), std::string::npos);
    auto withInf = good;
    withInf[7] = INFINITY;
    EXPECT_NE(loadError(writeNpy("inf.npy", goodDict, payload(withInf))).find("value inf at index (0, 0, 7) is not finite"), std::string::npos);
    auto outOfRange = good;
    outOfRange[99] = 250.0f;
    EXPECT_NE(loadError(writeNpy("range.npy", goodDict, payload(outOfRange))).find("value 250 at index (0, 0, 99) is out of range [20, 200]"),
              std::string::npos);
    // std::stoull's own std::invalid_argument ("stoull") left the reader, not a TensorError.
    EXPECT_NE(loadError(writeNpy("letters.npy", "{'descr': '<f4', 'fortran_order': False, 'shape': (101, abc, 101), }", payload(good)))
                  .find("shape entry 'abc' is not a whole number below 10^9"), std::string::npos);
    EXPECT_NE(loadError(writeNpy("huge.npy", "{'descr': '<f4', 'fortran_order': False, 'shape': (101, 99999999999999999999999, 101), }", payload(good)))
                  .find("shape entry '99999999999999999999...' is not"), std::string::npos);
    EXPECT_NE(loadError(writeNpy("brace.npy", "{'descr': '<f4', 'fortran_order': False, 'shape': (101, 101, 101), ", payload(good)))
                  .find("header is not a dict"), std::string::npos);  // numpy refuses it too
}

TEST(LookupTensor, AShapeWhoseValuesOverflowTheByteCountIsRefused)
{
    // 2^21 * 2^21 * 2^22 = 2^64 values wrapped around to 0: a header-only file passed the size check, and the
    // first lookup read memory that was never there.
    const std::array<std::size_t, 3> shape{2097152u, 2097152u, 4194304u};
    const std::string path =
        writeNpy("wraps.npy", "{'descr': '<f4', 'fortran_order': False, 'shape': (2097152, 2097152, 4194304), }", "");
    try
    {
        LookupTensor::load(path, TensorSpec{shape, 20.0, 200.0});
        ADD_FAILURE() << "the shape was taken";
    }
    catch (const TensorError &error)
    {
        EXPECT_NE(std::string(error.what()).find("holds more values than memory can"), std::string::npos)
            << error.what();
    }
    EXPECT_THROW(LookupTensor(shape, {}), TensorError);
}

TEST(LookupTensor, AnInMemoryTensorMustBeFinite)
{
    // Built in memory, a NaN reached TensorPolicy's clamps as an empty optional (B = 1, psi_K = 0.14 in a review).
    auto values = std::vector<float>(8u, 50.0f);
    values[5] = NAN;
    try
    {
        LookupTensor tensor({2u, 2u, 2u}, values);
        ADD_FAILURE() << "a NaN value was taken";
    }
    catch (const TensorError &error)
    {
        EXPECT_NE(std::string(error.what()).find("tensor: value nan at index (1, 0, 1) is not finite"), std::string::npos)
            << error.what();
    }
    values[5] = 50.0f;
    EXPECT_DOUBLE_EQ(LookupTensor({2u, 2u, 2u}, values).trilinear(0.3, 0.6, 0.9), 50.0);
}

TEST(TensorPolicy, LooksUpRawFeaturesAndClamps)
{
    auto b = std::make_shared<LookupTensor>(std::array<std::size_t, 3>{N, N, N}, affineValues());
    TensorPolicy policy(b, nullptr, Interpolation::Trilinear);
    EXPECT_FALSE(policy.decidesNeighbourFactor());  // no K tensor: psi_K stays e
    DecisionContext context;
    context.kind = DecisionKind::BatchSize;
    context.features = Features{0.5, 0.2, 0.9, 0.4};  // rho_global, rho_local_B, rho_local_K, m
    EXPECT_DOUBLE_EQ(policy.decide(context), std::round(affine(0.5, 0.2, 0.4)));
    context.kind = DecisionKind::NeighbourFactor;
    EXPECT_DOUBLE_EQ(policy.decide(context), M_E);

    EXPECT_EQ(policy.initialBatchSize(), 200);  // with a B tensor: the top of the range, as FIT*
    EXPECT_EQ(TensorPolicy(nullptr, b, Interpolation::Nearest).initialBatchSize(), 100);  // fixed B

    TensorPolicy both(b, b, Interpolation::Nearest);
    EXPECT_TRUE(both.decidesNeighbourFactor());
    EXPECT_DOUBLE_EQ(both.decide(context), 15.0);  // affine values >= 20 clamp to psi_K's maximum
}
