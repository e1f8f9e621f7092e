/* io/gltf_export_up.c: the lightmap's scene's up axis for the glTF export
 * (io/gltf_export_up.h says why this is a file of its own). */
#include "io/gltf_export_up.h"
#include "lightmap/lightmap_internal.h"

gi_up_axis gi__lightmap_up(const gi_lightmap *lm) { return lm ? gi_scene_up(lm->scene) : GI_UP_Y; }
