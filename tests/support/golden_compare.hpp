// Comparing a result with a pack tensor: the shapes must agree (a leading batch of one is ignored on either
// side, since the pack writes B = 1 where the engine has no batch dimension), then every element must satisfy
// |ours − golden| ≤ atol + rtol·|golden| (NaN fails). Prints the worst difference, returns it.
#pragma once
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "io/host_tensor.hpp"

namespace dvs::test {

// The shape without leading 1s (the pack's B = 1), keeping at least one dimension.
inline Shape without_batch(Shape s) {
  while (s.size() > 1 && s.front() == 1) s.erase(s.begin());
  return s;
}

inline std::string shape_text(const Shape& s) {
  std::ostringstream o;
  o << '[';
  for (size_t i = 0; i < s.size(); ++i) o << (i ? "," : "") << s[i];
  o << ']';
  return o.str();
}

// Shapes as the engine and the pack write them agree (testing::AssertionResult, to name both on failure).
inline ::testing::AssertionResult same_shape(const Shape& ours, const Shape& golden) {
  if (without_batch(ours) == without_batch(golden)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "shape " << shape_text(ours) << " where the pack has " << shape_text(golden);
}

// Element-wise check of `ours` against `golden` values laid out in `golden_shape`. Returns max |diff|
// (infinity when a value is NaN or the shapes differ).
inline double expect_close_values(const std::string& what, const Shape& ours_shape, const std::vector<float>& a,
                                  const Shape& golden_shape, const std::vector<float>& g, double atol, double rtol) {
  const auto shapes = same_shape(ours_shape, golden_shape);
  EXPECT_TRUE(shapes) << what;
  if (!shapes || a.size() != g.size()) {
    ADD_FAILURE() << what << ": " << a.size() << " values where the pack has " << g.size();
    return INFINITY;
  }
  double worst = 0;
  size_t bad = 0, first_bad = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double d = std::fabs(double(a[i]) - double(g[i]));
    worst = std::max(worst, std::isnan(d) ? INFINITY : d);
    if (!(d <= atol + rtol * std::fabs(double(g[i])))) {
      if (bad == 0) first_bad = i;
      ++bad;
    }
  }
  std::printf("  %-44s max |diff| = %.3e (atol %g, rtol %g)\n", what.c_str(), worst, atol, rtol);
  EXPECT_EQ(bad, 0u) << what << ": " << bad << " of " << a.size() << " values outside |diff| <= " << atol << " + "
                     << rtol << "·|golden|, max |diff| " << worst << ", first at flat index " << first_bad << " (ours "
                     << a[first_bad] << ", pack " << g[first_bad] << ")";
  return worst;
}

inline double expect_close(const std::string& what, const HostTensor& ours, const HostTensor& golden, double atol,
                           double rtol) {
  return expect_close_values(what, ours.shape, ours.to_f32(), golden.shape, golden.to_f32(), atol, rtol);
}

}  // namespace dvs::test
