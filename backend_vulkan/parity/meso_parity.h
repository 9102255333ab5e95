#pragma once
// CPU/GPU parity of the mesostructure marchers: shaders/meso/march.glsl (through
// shaders/meso/parity_meso.comp) against include/dispmap/meso/march.h in float, on the same
// float rays. On a strict device (lavapipe) it compares the hit flag, the bits of t and the
// iteration count; on another, the hit: |t| within 1/16 voxel and the same hit or miss for all
// but 0.1 % of the rays (meso_parity.cpp says why). One table row per method and knob set
// ("march ..."), in parity::run's table.
#include <vector>

#include "dispmap/meso/march.h"
#include "parity.h"

namespace dispmap::parity {

/// The hard cases in one tiling field (as tests/test_meso_support.h's hardField): a slope, a
/// wall one texel wide at i = 2 almost the full depth, a one-texel spike to the top, a cliff
/// (a step of 40 % of the depth) near i = width - 3 and a flat floor at 0 for j < 2.
MesoHeightField mesoParityField(int width, int height, int layers);

/// The solid of the solid rows: four beads (meso/solid.h's UV spheres) in 16 x 16 x 16 voxels,
/// one standing on the floor, one floating, two across the tile's sides x = 0 and y = 16 (their
/// entries name the tiles before and after: negative and positive shifts).
MesoSolid mesoParitySolid();

/// The marcher rows: Donnelly's distance map (fixed count, eps), the compressed DDM (4 x 1
/// cones with shadow cones and isotropic; with and without quadrics; both exit rules; view,
/// grazing, inside-the-solid and upward shadow rays), relief mapping, POM and the solid's
/// march (4 x 1 + shadow cones and isotropic, both exit rules; the triangle hit compared too). `rays` rays per
/// row (0: Options::mesoRays).
std::vector<KernelResult> runMeso(vulkan::Context& context, const Options& options);

} // namespace dispmap::parity
