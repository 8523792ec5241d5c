#include "dhfcast/directions.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "dhfcast/error.h"

namespace dhfcast {
namespace {

// Angle (radians) from each direction to its nearest other direction.
std::vector<double> nearest_angles(const std::vector<Vec3>& dirs) {
  std::vector<double> nn(dirs.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < dirs.size(); ++i)
    for (std::size_t j = 0; j < dirs.size(); ++j)
      if (i != j) nn[i] = std::min(nn[i], std::acos(std::clamp(dirs[i].dot(dirs[j]), -1.0, 1.0)));
  return nn;
}

TEST(FibonacciDirections, AreUnitAndBalanced) {
  const std::vector<Vec3> dirs = fibonacci_directions(512);
  ASSERT_EQ(dirs.size(), 512u);
  Vec3 mean = Vec3::Zero();
  for (const Vec3& d : dirs) {
    EXPECT_NEAR(d.norm(), 1.0, 1e-12);
    mean += d;
  }
  EXPECT_LT((mean / 512.0).norm(), 0.01);
}

TEST(FibonacciDirections, NearestNeighbourDistancesAreUniform) {
  for (int n : {64, 512}) {
    SCOPED_TRACE(n);
    const std::vector<double> nn = nearest_angles(fibonacci_directions(n));
    const auto [lo, hi] = std::minmax_element(nn.begin(), nn.end());
    EXPECT_GT(*lo, 0.0);
    EXPECT_LT(*hi / *lo, 2.5);
  }
}

TEST(FibonacciDirections, EveryAxisHasANearbyDirection) {
  const int n = 512;
  const std::vector<Vec3> dirs = fibonacci_directions(n);
  const double radius = 2.0 * std::sqrt(4.0 * std::numbers::pi / n);
  for (int axis = 0; axis < 3; ++axis)
    for (double s : {-1.0, 1.0}) {
      const Vec3 a = s * Vec3::Unit(axis);
      double best = std::numeric_limits<double>::infinity();
      for (const Vec3& d : dirs) best = std::min(best, std::acos(std::clamp(a.dot(d), -1.0, 1.0)));
      EXPECT_LT(best, radius) << "axis " << axis << " sign " << s;
    }
}

TEST(FibonacciDirections, AreDeterministicAndDistinct) {
  const std::vector<Vec3> a = fibonacci_directions(300), b = fibonacci_directions(300);
  EXPECT_EQ(a, b);
  const std::vector<double> nn = nearest_angles(a);
  EXPECT_GT(*std::min_element(nn.begin(), nn.end()), 1e-3);
}

TEST(FibonacciDirections, OneDirectionIsValidZeroIsNot) {
  EXPECT_EQ(fibonacci_directions(1).size(), 1u);
  EXPECT_NEAR(fibonacci_directions(1)[0].norm(), 1.0, 1e-12);
  try {
    fibonacci_directions(0);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::InvalidOptions);
  }
}

}  // namespace
}  // namespace dhfcast
