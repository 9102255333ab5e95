#pragma once
// The swimming figure (texel-ratio rule): how far the tessellated default scene moves per unit of a
// continuously changing tessellation factor, with and without mip selection.
#include <ostream>
#include <string>

namespace dispmap::figures {
/// Sweeps a uniform FractionalEven factor over the default scene (tiles of 2^5, sub-faces
/// 2^4), prints max/RMS swim speed and the error against the finest surface per mip setting,
/// and writes `csvPath` if not empty. Throws dispmap::Error.
void printSwimFigure(std::ostream& out, const std::string& csvPath);
} // namespace dispmap::figures
