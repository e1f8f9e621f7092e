/* gi.h: the core's umbrella header. Ownership, pointer lifetimes and
 * thread-safety are stated in each subject header it includes. */
#ifndef GI_H
#define GI_H
#include "gi_error.h"
#include "gi_scene.h"
#include "gi_city.h"
#include "gi_quality.h"
#include "gi_cancel.h"
#include "gi_cascade.h"
#include "gi_probe.h"
#include "gi_output.h"
#include "gi_camera.h"
#include "gi_reference.h"
#include "gi_render.h"
#include "gi_exr.h"
#include "gi_vdb.h"
#include "gi_points.h"
#include "gi_cpu.h"
#include "gi_batch.h"
#include "gi_lightmap.h"
#include "gi_move.h"
#endif
