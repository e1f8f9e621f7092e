/* gi_output.h: files for clients and viewers: probe and panorama EXRs,
 * the cascade as OpenVDB, and PNG pictures.
 *
 * Every writer writes to a temporary name beside `path` and renames it into
 * place, so a failure never leaves a partial file and never loses the file
 * that was there. Inputs are borrowed for the call only. Writers are
 * thread-safe for different paths (one call per path at a time). */
#ifndef GI_OUTPUT_H
#define GI_OUTPUT_H

#include <stddef.h>
#include "gi_cascade.h"
#include "gi_error.h"
#include "gi_probe.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Writes probes as an EXR, one pixel per probe in a row: channels R,G,B
 * (irradiance), direct.R/G/B, indirect.R/G/B, ao.Y (when ao ran) and the 27
 * sh.L00.R ... sh.L22.B; header attributes from the report. */
gi_result gi_probes_write_exr(const char *path, const gi_probe *probes, size_t n,
                              const gi_scene *scene, const double at[3],
                              const gi_bake_report *rep, int use_half, gi_error_info *err);

/* Extra string attributes for the EXR writers (name and value borrowed). */
typedef struct gi_exr_extra {
  const char *name;
  const char *value;
} gi_exr_extra;

/* gi_probes_write_exr with extra header attributes (timings, cache state):
 * at most 16, none named as an attribute the writer sets (gi.scene,
 * gi.viewpoint, gi.quality, gi.effects, gi.version, gi.kind, gi.sh,
 * gi.panorama); more is GI_ERR_LIMIT, such a name GI_ERR_INVALID_ARG. */
gi_result gi_probes_write_exr_ex(const char *path, const gi_probe *probes, size_t n,
                                 const gi_scene *scene, const double at[3],
                                 const gi_bake_report *rep, int use_half,
                                 const gi_exr_extra *extra, size_t num_extra, gi_error_info *err);

/* Writes a panorama as EXR: R,G,B (direct + indirect radiance), direct.R/G/B,
 * indirect.R/G/B; header gi.kind = "panorama" plus the probe attributes. */
gi_result gi_panorama_write_exr(const char *path, int w, int h, const float *direct,
                                const float *indirect, const gi_scene *scene, const double at[3],
                                const gi_bake_report *rep, int use_half,
                                const gi_exr_extra *extra, size_t num_extra, gi_error_info *err);

/* Writes the cascade snapshot as VDB: per level L<d>_density (fog),
 * L<d>_Cd (radiance), L<d>_albedo, L<d>_normal, and the finest level as
 * plain density and Cd. faces = 1 adds per-face grids L<d>_face_px ... */
gi_result gi_cascade_write_vdb(const gi_cascade *c, const char *path, int faces,
                               gi_error_info *err);
/* The memory gi_cascade_write_vdb holds while it writes c (its dense
 * copies of every level: levels x res^3 x 10 floats, 28 with faces), for
 * callers that admit work by bytes: at 8 levels of 64^3 with faces it is
 * 235 MB whatever the cascade holds. */
size_t gi_cascade_vdb_bytes_estimate(const gi_cascade *c, int faces);

/* Writes an 8-bit sRGB PNG from linear RGB floats times `exposure`,
 * through a temporary file renamed into place. */
gi_result gi_image_write_png(const char *path, const float *rgb, int width, int height, float exposure,
                             gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
