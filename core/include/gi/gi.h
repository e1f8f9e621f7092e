/* gi.h: the core's umbrella header. */
#ifndef GI_H
#define GI_H
#include "gi_error.h"
#include "gi_scene.h"
#include "gi_city.h"
#include "gi_bake.h"
#include "gi_reference.h"
#include "gi_render.h"
#include "gi_exr.h"
#include "gi_vdb.h"
#include "gi_points.h"
#endif
