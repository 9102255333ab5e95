#pragma once
// Fixture of the layering test: a core header that reaches up into surface/.
#include <vector>
#include "dispmap/surface/mesh.h"
