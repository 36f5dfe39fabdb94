#pragma once
// Memory estimates checked before a large allocation, so that a job too big for the machine
// fails at once (InvalidInput: exit 3 in the CLI) with a message naming the parameter that made
// it big, instead of dying minutes later with a bare std::bad_alloc.

#include <cstddef>
#include <string>

namespace spacewarp::detail {

/// The bytes this process can still allocate: the smallest of /proc/meminfo's MemAvailable,
/// RLIMIT_AS minus the current virtual size, RLIMIT_DATA minus the current data size, the
/// cgroup's memory.max minus memory.current, and the cap set by setMemoryCap. SIZE_MAX when
/// none of them is known.
std::size_t availableMemory();

/// A process-wide cap on what availableMemory() reports (default SIZE_MAX: none), for hosts that
/// bound their jobs by other means than limits, such as the rig fuzzer (whose sanitizer cannot
/// run under RLIMIT_AS).
void setMemoryCap(std::size_t bytes);

/// "1.5 GB", "320 MB", "12 kB": a byte count for messages.
std::string formatBytes(double bytes);

/// Throws InvalidInput "<what> needs about <bytes> of memory, more than the <available>
/// available" when `bytes` exceeds availableMemory(). `what` names the parameter at fault
/// (e.g. "'spacing' 0.001 (1,300,000 graph nodes)"). `bytes` is a double so that estimates
/// computed from huge counts do not wrap.
void checkMemory(double bytes, const std::string& what);

}  // namespace spacewarp::detail
