/* io/gltf_export_up.h: which way is up in a lightmap's scene, for
 * io/gltf_export.cpp, which cannot include the core's internal C11
 * headers (their atomics are not C++'s). */
#ifndef GI_GLTF_EXPORT_UP_H
#define GI_GLTF_EXPORT_UP_H

#include "gi/gi_lightmap.h"
#include "gi/gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The up axis of the scene lm was laid out on (GI_UP_Y for NULL). Thread-safe. */
gi_up_axis gi__lightmap_up(const gi_lightmap *lm);

#ifdef __cplusplus
}
#endif

#endif
