#pragma once
// Height fields for the mesostructure tests (generated: no file needed).
#include <algorithm>
#include <cmath>
#include <functional>

#include "dispmap/meso/march.h"

namespace dmtest {

/// A width x height x layers field with heights f(i, j) (clamped into [0, layers]).
inline dispmap::MesoHeightField mesoField(int width, int height, int layers, const std::function<double(int, int)>& f) {
    std::vector<float> h(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
    for (int j = 0; j < height; ++j)
        for (int i = 0; i < width; ++i)
            h[static_cast<std::size_t>(j * width + i)] = static_cast<float>(std::clamp(f(i, j), 0.0, static_cast<double>(layers)));
    return dispmap::mesoHeightField(width, height, layers, std::move(h));
}

/// The hard cases in one field: a smooth slope, a wall one texel wide (column i = 2, almost
/// the full depth), a one-texel spike, a cliff (a step of 40 % of the depth between two
/// texels) and a flat floor at 0.
inline dispmap::MesoHeightField hardField(int width, int height, int layers) {
    const double L = layers;
    return mesoField(width, height, layers, [=](int i, int j) {
        if (i == 2) return L - 0.25;                            // thin wall
        if (i == width / 2 && j == height / 2) return L;        // spike to the top
        if (j < 2) return 0.0;                                  // floor
        double h = 0.2 * L + 0.1 * L * std::sin(0.9 * i + 0.4 * j);
        if (i >= width - 3) h += 0.4 * L;                       // cliff
        return h;
    });
}

} // namespace dmtest

