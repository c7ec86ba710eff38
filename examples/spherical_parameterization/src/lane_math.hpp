// Elementary functions written so that loops over them vectorize (no calls, no branches).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace sphparam {

/// ln x for a normal, finite x > 0, within 4 ulp of std::log (3 measured: LaneMath test); for
/// anything else an unspecified number (callers check is_normal_positive and use std::log
/// there). Integer operations split x into 2^e m with m in [√½, √2), and ln m = 2 atanh(s),
/// s = (m − 1)/(m + 1), is summed to s^21: |s| ≤ 0.1716, so the next term is below 2^-54 of the
/// sum. The local energies call it for every face in a block at once; glibc's log, a call per
/// face, kept those loops scalar.
inline double log_of_normal(double x) {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &x, sizeof bits);
  const std::uint64_t mantissa_bits = (bits & 0x000FFFFFFFFFFFFFull) | 0x3FF0000000000000ull;  // 1.f
  const std::uint64_t exponent_bits = (bits >> 52) | 0x4330000000000000ull;                    // 2^52 + biased exponent
  double m = 0, e = 0;
  std::memcpy(&m, &mantissa_bits, sizeof m);
  std::memcpy(&e, &exponent_bits, sizeof e);
  e -= 4503599627370496.0 + 1023.0;  // exact: the unbiased exponent
  const bool upper = m > 1.4142135623730951;
  m = upper ? 0.5 * m : m;
  e = upper ? e + 1 : e;
  const double s = (m - 1) / (m + 1), s2 = s * s;
  // Horner, written out: 1 + s²/3 + s⁴/5 + … + s²⁰/21
  double series = 1.0 / 21;
  series = series * s2 + 1.0 / 19;
  series = series * s2 + 1.0 / 17;
  series = series * s2 + 1.0 / 15;
  series = series * s2 + 1.0 / 13;
  series = series * s2 + 1.0 / 11;
  series = series * s2 + 1.0 / 9;
  series = series * s2 + 1.0 / 7;
  series = series * s2 + 1.0 / 5;
  series = series * s2 + 1.0 / 3;
  series = series * s2 + 1.0;
  // ln 2 as a head with zeros in its last bits (e × head is exact) and a tail
  constexpr double ln2_head = 0.693147180369123816490, ln2_tail = 1.90821492927058770002e-10;
  return e * ln2_head + (2 * s * series + e * ln2_tail);
}

/// True for the arguments log_of_normal takes: normal, finite and positive (false for NaN).
inline bool is_normal_positive(double x) {
  return x >= std::numeric_limits<double>::min() && x <= std::numeric_limits<double>::max();
}

}  // namespace sphparam
