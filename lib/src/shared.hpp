// Small helpers shared by the library's sources (not installed).
#pragma once

#include <cctype>
#include <string>

namespace relit::detail {

/// `s` in lower case (ASCII).
inline std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

inline constexpr double kPi = 3.14159265358979323846;

}  // namespace relit::detail
