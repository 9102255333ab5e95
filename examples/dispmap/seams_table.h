#pragma once
// `dispmap bench`: the seams table (docs/figures.md, "Seams"): edge position gap and normal jump
// before and after the sharp-feature and end-cap rules, per shape class, and what each rule
// costs per evaluation (CPU) and per frame (the Vulkan device).
#include <ostream>
#include <string>

namespace dispmap::figures {

/// Prints the table; also writes it as CSV to csvPath unless empty. `device` selects the Vulkan
/// device of the frame-time columns ("" = lavapipe, or the first device).
void printSeamsTable(std::ostream& out, const std::string& csvPath, const std::string& device = "");

} // namespace dispmap::figures
