#pragma once
// The names of an option's enum values (rig keys, Python arguments): one table per enum gives
// both directions, and an unknown name is refused listing the known ones.

#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <utility>

#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

template <class Enum, std::size_t N>
using EnumNames = std::array<std::pair<Enum, std::string_view>, N>;

/// The name of `value` in `names` ("unknown" for a value not in the table).
template <class Enum, std::size_t N>
std::string enumName(const EnumNames<Enum, N>& names, Enum value) {
  for (const auto& [v, name] : names)
    if (v == value) return std::string(name);
  return "unknown";
}

/// The value named `name`; throws InvalidInput "<what> '<name>' is not one of: a, b, c".
template <class Enum, std::size_t N>
Enum enumFromName(const EnumNames<Enum, N>& names, std::string_view name, std::string_view what) {
  std::string known;
  for (const auto& [v, n] : names) {
    if (n == name) return v;
    known += known.empty() ? "" : ", ";
    known += n;
  }
  std::string message(what);
  message += " '";
  message += name;
  message += "' is not one of: " + known;
  throw InvalidInput(message);
}

}  // namespace spacewarp::detail
