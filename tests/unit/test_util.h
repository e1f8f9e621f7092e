/* test_util.h: small helpers shared by the unit tests. */
#ifndef GI_TEST_UTIL_H
#define GI_TEST_UTIL_H

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

/* Path of a shared scene file, or NULL (after printing a loud SKIP line)
 * when ../shared/scenes is absent. Static buffer: not thread-safe. */
const char *tu_scene_path(const char *rel);
/* A fresh temporary directory for this test binary (created once). */
const char *tu_tmpdir(void);
/* Writes len bytes to tmpdir/name and returns the full path (static buffer rotation of 8). */
const char *tu_write_file(const char *name, const void *data, size_t len);

/* Runs a shell command; returns its stdout (static buffer, 64 KiB) and sets
 * *status to its exit code (-1 when it did not exit normally). */
const char *tu_run(const char *cmd, int *status);

struct gi_scene;
struct gi_mesh_builder;
struct gi_light;
/* Builds b (freed) into a y-up scene named name with n extra lights,
 * asserting it builds. Caller releases it. */
struct gi_scene *tu_build(struct gi_mesh_builder *b, const char *name, const struct gi_light *lights, size_t n);
/* The same with up axis `up` (a gi_up_axis value: GI_UP_Y or GI_UP_Z). */
struct gi_scene *tu_build_up(struct gi_mesh_builder *b, const char *name, int up, const struct gi_light *lights,
                             size_t n);

/* The closed white furnace: a cube [0,size]^3 of albedo a whose walls emit
 * Le inward (test_furnace, test_hardcases). Caller releases it. */
struct gi_scene *tu_furnace_scene(double size, double a, double Le);
/* The same with walls that are also perfect mirrors reflecting m (a glossy
 * lobe of roughness 0): every wall reflects a + m of what arrives. */
struct gi_scene *tu_furnace_scene_mirror(double size, double a, double m, double Le);

/* The plane y = 0 over x in [-100, 100], z in [-100, z_max], albedo a, under
 * a sun of irradiance E travelling along (sin 60, -cos 60, 0): the plane
 * receives E cos 60 (test_render, test_views, test_ref_panorama). */
struct gi_scene *tu_sunlit_plane(double a, double E, double z_max);

/* A closed room [-2,2] x [0,2.5] x [-2,2] of albedo a (grey) with a block
 * on its floor at x, z in [-1.6,-0.9], 0.7 high, lit by a point light of
 * 20 W/sr at (0.8, 2.0, 0.8): edges, a lit side and a shadowed one
 * (test_render, test_ref_panorama). Caller releases it. */
struct gi_scene *tu_lit_room(float a);

/* A solid box [-0.5,0.5] x [0,1] x [-0.5,0.5] (outward faces) on a floor
 * 10 x 10 at y = 0, albedo 0.5, under a uniform sky of 1: a viewpoint at
 * the box's centre sees no sky (test_effects, test_lightmap). */
struct gi_scene *tu_box_on_sky_floor(void);

/* ThreadSanitizer runs code 5-15x slower and keeps 4 bytes of shadow for
 * each byte of memory touched: a test's bounds on wall time and on RSS
 * growth scale by this under `make tsan` (1 in every other build). */
#if defined(__SANITIZE_THREAD__)
#define TU_TSAN_FACTOR 5
#else
#define TU_TSAN_FACTOR 1
#endif

#define TU_SKIP_IF_NO_SCENE(var, rel)                  \
  const char *var = tu_scene_path(rel);                \
  if (!var) { skip(); }

#endif
