#include <spacewarp/core/errors.h>

#include <cstdio>

namespace spacewarp {

std::string printable(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", byte);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out;
}

std::string prefixed(const std::string& name, const std::string& what) {
  return what.rfind(name, 0) == 0 ? what : name + ": " + what;
}

}  // namespace spacewarp
