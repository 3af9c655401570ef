#include "comparison_image.h"

#include <gtest/gtest.h>

#include "error.h"
#include "percentile.h"

namespace phongfit {
namespace {

// Four pixels in a row: outside, left out, predicted too bright, predicted too dark.
ComparisonPanels fourPixels() {
    ComparisonPanels panels;
    panels.width = 4;
    panels.height = 1;
    panels.observed = {Color3::Zero(), Color3::Constant(0.5), Color3::Constant(1.0),
                       Color3::Constant(0.25)};
    panels.state = {ComparePixel::Outside, ComparePixel::LeftOut, ComparePixel::Compared,
                    ComparePixel::Compared};
    panels.predicted = {
        {Color3::Zero(), Color3::Zero(), Color3::Constant(1.5), Color3::Constant(0.0)}};
    panels.whitePercentile = 100;
    return panels;
}

// The value at rank p% of the sample's size, whatever its order: the white level here, the edge
// check's median deviation (p = 50: the upper median of an even count).
TEST(Percentile, IsTheValueAtItsRank) {
    const std::vector<double> values = {5, 1, 4, 2, 3};
    EXPECT_EQ(percentile(values, 0), 1);
    EXPECT_EQ(percentile(values, 50), 3);
    EXPECT_EQ(percentile(values, 99), 5);
    EXPECT_EQ(percentile(values, 100), 5);
    EXPECT_EQ(percentile({4, 1, 3, 2}, 50), 3);
    EXPECT_EQ(percentile({}, 50), 0);
}

TEST(ComparisonImage, ColumnsShowObservedPredictedAndSignedError) {
    const cv::Mat image = comparisonImage(fourPixels());
    ASSERT_EQ(image.rows, 1);
    ASSERT_EQ(image.cols, 12);
    const auto at = [&](int column, int x) { return image.at<cv::Vec3b>(0, 4 * column + x); };
    for (int column = 0; column < 3; ++column) EXPECT_EQ(at(column, 0), cv::Vec3b(0, 0, 0));
    EXPECT_EQ(at(0, 1)[0], at(0, 1)[2]) << "the left-out pixel's observation is shown";
    EXPECT_GT(at(0, 1)[0], 100);
    EXPECT_EQ(at(1, 1), cv::Vec3b(64, 64, 64));
    EXPECT_EQ(at(2, 1), cv::Vec3b(64, 64, 64));
    EXPECT_EQ(at(0, 2), cv::Vec3b(255, 255, 255)) << "the brightest observation is white";
    EXPECT_EQ(at(1, 2), cv::Vec3b(255, 255, 255)) << "one exposure for both columns";
    EXPECT_EQ(at(2, 2), cv::Vec3b(0, 0, 255)) << "too bright: red (BGR)";
    EXPECT_EQ(at(1, 3), cv::Vec3b(0, 0, 0));
    EXPECT_EQ(at(2, 3)[0], 255) << "too dark: blue";
    EXPECT_GT(at(2, 3)[0], at(2, 3)[2]);
}

TEST(ComparisonImage, RowsStackAndSizesAreChecked) {
    ComparisonPanels panels = fourPixels();
    panels.predicted.push_back(panels.observed);
    const cv::Mat image = comparisonImage(panels);
    EXPECT_EQ(image.rows, 2);
    EXPECT_EQ(image.at<cv::Vec3b>(1, 2 * 4 + 2), cv::Vec3b(255, 255, 255)) << "no error: white";
    panels.predicted[1].pop_back();
    EXPECT_THROW(comparisonImage(panels), Error);
    panels = fourPixels();
    panels.state.pop_back();
    EXPECT_THROW(comparisonImage(panels), Error);
}

}  // namespace
}  // namespace phongfit
