#pragma once
// What the process has used, for benchmarks (the `sdot bench` line, `python -m sdot.bench`).

namespace sdot {

/// The peak resident memory of this process so far, in MB (2^20 bytes): Linux's VmHWM, which
/// starts afresh at exec, so a program launched by a large process reports only its own; on
/// other systems getrusage's ru_maxrss.
double peak_resident_memory_mb();

}  // namespace sdot
