#include "sdot/resources.hpp"

#include <sys/resource.h>

#include <cstdlib>
#include <fstream>
#include <string>

namespace sdot {

double peak_resident_memory_mb() {
  // ru_maxrss keeps the parent's high-water mark from before exec, so a command started by a
  // Python benchmark driver would report the driver's memory; VmHWM is this program's own.
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::strtod(line.c_str() + 6, nullptr) / 1024.0;
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

}  // namespace sdot
