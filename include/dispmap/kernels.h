#pragma once
// All kernels of dispmap (GLM only). See kernels/prelude.h for how they mirror into GLSL.
#include "dispmap/kernels/bspline.h"
#include "dispmap/kernels/lod.h"
#include "dispmap/kernels/tile.h"
#include "dispmap/kernels/normal.h"
#include "dispmap/kernels/meso.h"
