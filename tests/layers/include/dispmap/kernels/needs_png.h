#pragma once
// Fixture of the layering test: a kernel header that needs libpng.
#include <png.h>
