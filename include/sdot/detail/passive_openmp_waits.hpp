#pragma once
/// \file passive_openmp_waits.hpp
/// For the commands' main(): OpenMP threads that wait for work sleep instead of spinning.

#include <cstdlib>
#if defined(__linux__)
#include <unistd.h>
#endif

namespace sdot::detail {

/// Runs the program again, once, with OMP_WAIT_POLICY=passive, unless the environment sets a
/// wait policy or a spin count (or `guard_variable`, which the re-run gets). libgomp reads its
/// environment before main, hence the re-run. With a core taken by another process, spinning
/// threads take the time the working ones need (sdot bench, sphere, 10⁵ sites, one busy loop
/// beside it: 1.93–2.11 s spinning, 1.65–1.68 s passive); on an idle machine the two differ by
/// about 1 %. Returns only when it does not re-run (or exec fails: libgomp's defaults then).
inline void rerun_with_passive_openmp_waits([[maybe_unused]] char** argv, [[maybe_unused]] const char* guard_variable) {
#if defined(__linux__) && defined(_OPENMP)
  if (std::getenv("OMP_WAIT_POLICY") || std::getenv("GOMP_SPINCOUNT") || std::getenv(guard_variable)) return;
  setenv("OMP_WAIT_POLICY", "passive", 1);
  setenv(guard_variable, "1", 1);  // never twice, whatever libgomp does
  execv("/proc/self/exe", argv);
#endif
}

}  // namespace sdot::detail
