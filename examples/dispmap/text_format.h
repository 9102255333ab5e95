#pragma once
// Number formatting of the tables the dispmap program prints.
#include <cstdio>
#include <string>

namespace dispmap::figures {

/// v with `digits` digits after the point.
inline std::string fixed(double v, int digits) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", digits, v);
    return b;
}

/// v in scientific notation with 3 significant digits.
inline std::string sci(double v) {
    char b[64];
    std::snprintf(b, sizeof b, "%.2e", v);
    return b;
}

} // namespace dispmap::figures
