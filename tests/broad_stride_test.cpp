#include "broad_stride.h"

#include <gtest/gtest.h>

namespace phongfit {
namespace {

// A round's estimate with a clear lobe (ks 0.5 +- 0.05) at n +- nStd.
MaterialFit solvedAt(double n, double nStd) {
    MaterialFit m;
    m.kd = Color3::Constant(0.4);
    m.ks = Color3::Constant(0.5);
    m.kdStd = Color3::Constant(0.01);
    m.ksStd = Color3::Constant(0.05);
    m.n = n;
    m.nStd = nStd;
    return m;
}

PhongMaterial recordedAt(double n) {
    PhongMaterial m;
    m.kd = Color3::Constant(0.4);
    m.ks = Color3::Constant(0.5);
    m.n = n;
    return m;
}

// 0128's round 1 (Cornell box, 40-degree light, n 300 from 30000): n 15333 +- 32700 recorded
// at 30000 records next at 30000 / 4; an estimate broader than that is recorded at itself.
TEST(BroadStride, AnUnresolvedBroaderEstimateRecordsBroaderByTheStride) {
    const auto stride =
        broadStride({solvedAt(15333, 32700)}, {recordedAt(30000)}, {recordedAt(15333)});
    ASSERT_TRUE(stride.has_value());
    EXPECT_DOUBLE_EQ((*stride)[0].n, 30000 / kBroadStride);
    EXPECT_DOUBLE_EQ((*stride)[0].ks[0], 0.5);  // only n moves

    const auto further =
        broadStride({solvedAt(219.75, 936)}, {recordedAt(6786)}, {recordedAt(219.75)});
    ASSERT_TRUE(further.has_value());
    EXPECT_DOUBLE_EQ((*further)[0].n, 219.75);
}

TEST(BroadStride, OnlyAFreeUnresolvedBroaderLobeStrides) {
    EXPECT_TRUE(stridesBroader(solvedAt(1000, 2000), 3000));
    // Resolved within a factor 3: the paths, not the recording's n, are what it lacks.
    EXPECT_FALSE(stridesBroader(solvedAt(1000, 1999), 3000));
    // Sharper than its recording: the sharper probe's side.
    EXPECT_FALSE(stridesBroader(solvedAt(3000, 9000), 3000));
    EXPECT_FALSE(stridesBroader(solvedAt(4000, 9000), 3000));
    // No lobe standing out (ks within 3 standard errors of 0): n is anyone's.
    MaterialFit faint = solvedAt(1000, 2000);
    faint.ks = Color3::Constant(0.149);
    EXPECT_FALSE(stridesBroader(faint, 3000));
    faint.ks = Color3::Constant(0.151);
    EXPECT_TRUE(stridesBroader(faint, 3000));
    // Held.
    MaterialFit held = solvedAt(1000, 2000);
    held.unconstrained = {"n"};
    EXPECT_FALSE(stridesBroader(held, 3000));
}

TEST(BroadStride, EachMaterialStridesOnItsOwn) {
    const auto stride =
        broadStride({solvedAt(80, 50), solvedAt(500, 2000)}, {recordedAt(100), recordedAt(8000)},
                    {recordedAt(80), recordedAt(500)});
    ASSERT_TRUE(stride.has_value());
    EXPECT_DOUBLE_EQ((*stride)[0].n, 80);   // resolved: where it would record anyway
    EXPECT_DOUBLE_EQ((*stride)[1].n, 500);  // min(500, 8000 / 4)
    EXPECT_FALSE(broadStride({solvedAt(80, 50)}, {recordedAt(100)}, {recordedAt(80)}).has_value());
}

}  // namespace
}  // namespace phongfit
