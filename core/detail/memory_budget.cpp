#include <spacewarp/core/detail/memory_budget.h>

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

namespace {

constexpr std::size_t kUnknown = std::numeric_limits<std::size_t>::max();

std::atomic<std::size_t> cap{kUnknown};

// The value in kB of `key` in a "Key:   123 kB" file (/proc/meminfo, /proc/self/status).
std::size_t procKilobytes(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key, 0) != 0) continue;
    std::istringstream fields(line.substr(key.size()));
    unsigned long long kb = 0;
    if (fields >> kb) return static_cast<std::size_t>(kb) * 1024;
  }
  return kUnknown;
}

// A single number in a file ("max" or unreadable: unknown).
std::size_t fileNumber(const std::string& path) {
  std::ifstream in(path);
  unsigned long long value = 0;
  if (!(in >> value)) return kUnknown;
  return static_cast<std::size_t>(value);
}

// What is left under a limit given what is in use (0 if over it; unknown if either is).
std::size_t headroom(std::size_t limit, std::size_t used) {
  if (limit == kUnknown || used == kUnknown) return kUnknown;
  return limit > used ? limit - used : 0;
}

std::size_t rlimit(int resource) {
  struct rlimit limit {};
  if (getrlimit(resource, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return kUnknown;
  return static_cast<std::size_t>(limit.rlim_cur);
}

// The cgroup v2 folder of this process ("0::/path" in /proc/self/cgroup).
std::string cgroupFolder() {
  std::ifstream in("/proc/self/cgroup");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("0::", 0) == 0) return "/sys/fs/cgroup" + line.substr(3);
  return {};
}

}  // namespace

void setMemoryCap(std::size_t bytes) { cap.store(bytes); }

std::size_t availableMemory() {
  std::size_t available = std::min(cap.load(), procKilobytes("/proc/meminfo", "MemAvailable:"));
  available = std::min(available,
                       headroom(rlimit(RLIMIT_AS), procKilobytes("/proc/self/status", "VmSize:")));
  available = std::min(
      available, headroom(rlimit(RLIMIT_DATA), procKilobytes("/proc/self/status", "VmData:")));
  if (const std::string cgroup = cgroupFolder(); !cgroup.empty()) {
    available = std::min(available, headroom(fileNumber(cgroup + "/memory.max"),
                                             fileNumber(cgroup + "/memory.current")));
  }
  return available;
}

std::string formatBytes(double bytes) {
  const char* units[] = {"bytes", "kB", "MB", "GB", "TB", "PB", "EB"};
  int u = 0;
  while (bytes >= 1000.0 && u < 6) {
    bytes /= 1000.0;
    ++u;
  }
  char text[64];
  std::snprintf(text, sizeof text, u == 0 ? "%.0f %s" : "%.3g %s", bytes, units[u]);
  return text;
}

void checkMemory(double bytes, const std::string& what) {
  const std::size_t available = availableMemory();
  if (available == kUnknown || bytes <= static_cast<double>(available)) return;
  throw InvalidInput(what + " needs about " + formatBytes(bytes) + " of memory, more than the " +
                     formatBytes(static_cast<double>(available)) + " available");
}

}  // namespace spacewarp::detail
