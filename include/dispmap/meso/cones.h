#pragma once
// The direction cones of the directional distance maps (kernels/meso.h, dmConeIndex). GLM only.
#include <string>

#include "dispmap/meso/height_field.h"

namespace dispmap {

/// m x n cones per hemisphere (kernels/meso.h, dmConeIndex): m azimuth sectors in {1, 2, 4, 8},
/// n elevation bands in {1, 2}; view cones (downwards) always, shadow cones (upwards) when
/// `shadow`; `isotropic`: one cone of every direction (m, n ignored).
/// The most cones a set has (8 x 2 with shadow cones).
inline constexpr int kMaxCones = 32;

struct ConeSet {
    int m = 4, n = 1;
    bool shadow = false;
    bool isotropic = false;

    static ConeSet all() {
        ConeSet c;
        c.isotropic = true;
        return c;
    }
    int count() const { return isotropic ? 1 : m * n * (shadow ? 2 : 1); }
    /// The m argument of dmConeIndex (0: isotropic).
    int kernelM() const { return isotropic ? 0 : m; }
    void validate() const {
        if (isotropic) return;
        if (m == 0 || n == 0) throw ArgumentError("direction cones: zero cones (" + std::to_string(m) + " x " + std::to_string(n) + ")");
        if (!(m == 1 || m == 2 || m == 4 || m == 8) || !(n == 1 || n == 2))
            throw ArgumentError("direction cones: " + std::to_string(m) + " x " + std::to_string(n) +
                                " is not supported (m in {1, 2, 4, 8}, n in {1, 2})");
    }
    std::string name() const {
        return isotropic ? std::string("isotropic") : std::to_string(m) + "x" + std::to_string(n) + (shadow ? "+shadow" : "");
    }
    /// Azimuth [lo, hi] and elevation [lo, hi] (radians; elevation < 0 below the horizon) of cone c.
    void range(int c, double az[2], double el[2]) const {
        constexpr double pi = 3.14159265358979323846;
        if (isotropic) {
            az[0] = 0;
            az[1] = 2 * pi;
            el[0] = -pi / 2;
            el[1] = pi / 2;
            return;
        }
        const int sector = c % m, band = (c / m) % n, hemisphere = c / (m * n);
        az[0] = 2 * pi * sector / m;
        az[1] = 2 * pi * (sector + 1) / m;
        const double a0 = pi / 2 * band / n, a1 = pi / 2 * (band + 1) / n; // angle from the horizon
        if (hemisphere == 0) {
            el[0] = -a1;
            el[1] = -a0;
        } else {
            el[0] = a0;
            el[1] = a1;
        }
    }
};

/// "MxN" (e.g. "4x1"; M in {1, 2, 4, 8}, N in {1, 2}) or "isotropic", with shadow cones when
/// `shadow`. ArgumentError naming the text otherwise.
inline ConeSet parseConeSet(const std::string& text, bool shadow = false) {
    if (text == "isotropic") return ConeSet::all();
    const std::size_t x = text.find('x');
    const auto digits = [](const std::string& s) {
        return !s.empty() && s.size() < 4 && std::all_of(s.begin(), s.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
    };
    if (x == std::string::npos || !digits(text.substr(0, x)) || !digits(text.substr(x + 1)))
        throw ArgumentError("direction cones '" + text + "': expected MxN (e.g. 4x1) or isotropic");
    ConeSet c;
    c.m = std::stoi(text.substr(0, x));
    c.n = std::stoi(text.substr(x + 1));
    c.shadow = shadow;
    c.validate();
    return c;
}

} // namespace dispmap
