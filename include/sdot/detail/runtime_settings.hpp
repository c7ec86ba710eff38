#pragma once
/// \file runtime_settings.hpp
/// For the commands' main(): settings that the OpenMP runtime and glibc read from the
/// environment before main, applied by running the program again once.

#include <cstdlib>
#include <string>
#if defined(__linux__)
#include <unistd.h>
#endif

namespace sdot::detail {

/// What rerun_with_runtime_settings() asks for.
struct RuntimeSettings {
  /// OMP_WAIT_POLICY=passive: OpenMP threads that wait for work sleep instead of spinning.
  /// With a core taken by another process, spinning threads take the time the working ones need
  /// (sdot bench, sphere, 10⁵ sites, one busy loop beside it: 1.93–2.11 s spinning, 1.65–1.68 s
  /// passive); on an idle machine the two differ by about 1 %.
  bool passive_openmp_waits = true;
  /// GLIBC_TUNABLES=glibc.malloc.hugetlb=1 (glibc 2.35 and later; older ones ignore it): malloc
  /// asks for transparent huge pages on its heap and its large mappings, where the kernel gives
  /// them only on request (/sys/kernel/mm/transparent_hugepage/enabled: madvise). A process that
  /// allocates and fills arrays of many MB then takes one page fault per 2 MB instead of per
  /// 4 kB (sdot-sphere-param, spiky_120k: the initial map's CHOLMOD factorisations took 19,000
  /// and 31,000 page faults, 0.5 s each, against 1,000 and 200 with huge pages).
  bool heap_huge_pages = false;
};

/// The value of the tunable `name` in a GLIBC_TUNABLES string ("a=1:b=2"; the last one counts),
/// or "default" when it is not there.
inline std::string glibc_tunable(const char* tunables, const std::string& name) {
  std::string value = "default";
  for (std::string rest = tunables ? tunables : ""; !rest.empty();) {
    const auto end = rest.find(':');
    const std::string item = rest.substr(0, end);
    if (item.rfind(name + "=", 0) == 0) value = item.substr(name.size() + 1);
    rest = end == std::string::npos ? std::string() : rest.substr(end + 1);
  }
  return value;
}

/// The settings as this process has them, for reports: OMP_WAIT_POLICY (or "default") and
/// glibc.malloc.hugetlb in GLIBC_TUNABLES ("1": transparent huge pages requested; or "default").
inline std::string omp_wait_policy_setting() {
  const char* policy = std::getenv("OMP_WAIT_POLICY");
  return policy ? policy : "default";
}
inline std::string heap_huge_pages_setting() {
  return glibc_tunable(std::getenv("GLIBC_TUNABLES"), "glibc.malloc.hugetlb");
}

/// Runs the program again, once, with the environment `settings` asks for, unless the
/// environment already sets them (OMP_WAIT_POLICY or GOMP_SPINCOUNT for the wait policy; the
/// tunable glibc.malloc.hugetlb in GLIBC_TUNABLES for huge pages, added to the tunables there) or
/// sets `guard_variable`, which the re-run gets. Returns only when it does not re-run (or exec
/// fails: the runtimes' defaults then).
inline void rerun_with_runtime_settings([[maybe_unused]] char** argv, [[maybe_unused]] const char* guard_variable,
                                        [[maybe_unused]] RuntimeSettings settings = {}) {
#if defined(__linux__)
  if (std::getenv(guard_variable)) return;
  bool changed = false;
#if defined(_OPENMP)
  if (settings.passive_openmp_waits && !std::getenv("OMP_WAIT_POLICY") && !std::getenv("GOMP_SPINCOUNT")) {
    setenv("OMP_WAIT_POLICY", "passive", 1);
    changed = true;
  }
#endif
#if defined(__GLIBC__)
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if (settings.heap_huge_pages && glibc_tunable(tunables, "glibc.malloc.hugetlb") == "default") {
    const std::string requested =
        (tunables && *tunables ? std::string(tunables) + ":" : std::string()) + "glibc.malloc.hugetlb=1";
    setenv("GLIBC_TUNABLES", requested.c_str(), 1);
    changed = true;
  }
#endif
  if (!changed) return;
  setenv(guard_variable, "1", 1);  // never twice, whatever the runtimes do
  execv("/proc/self/exe", argv);
#endif
}

}  // namespace sdot::detail
