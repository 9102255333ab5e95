#pragma once
// `dispmap bench --only cores`: what all cores buy, stage by stage, measured in one run against
// one thread (docs/figures.md, "All cores"), and what each surface option costs at set-up.
#include <functional>
#include <ostream>
#include <string>

namespace dispmap::figures {

struct CoresTableArgs {
    std::string dataDir; ///< spot_control_mesh.obj and skimage_brick.png
    bool quick = false;  ///< smaller tiles, factors and one cone set (CI)
    std::string csv;     ///< also write the table as CSV
};

void printCoresTable(std::ostream& out, const CoresTableArgs& a);

/// Wall-clock seconds of one call of f.
double secondsOf(const std::function<void()>& f);

} // namespace dispmap::figures
