#pragma once
// Fixture of the GLM-only test: a core header that reaches libpng through a quoted include,
// which only the dependency stage (-M) sees.
#include "png.h"
