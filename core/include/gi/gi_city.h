/* gi_city.h: the embedded default scene, a deterministic procedural city.
 *
 * Same seed and size give the same triangles bit for bit on every machine
 * (integer PRNG, no libm calls in the layout). Y is up, metres. Streets on
 * a grid, blocks of buildings with varied heights and albedos, some
 * emissive windows and street lights; a sun and a sky. The functions keep
 * no state: they are thread-safe as long as each thread fills its own
 * builder. The built scene is the caller's (gi_scene_release). */
#ifndef GI_CITY_H
#define GI_CITY_H

#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_city_params {
  uint64_t seed;        /* 0 = default seed 1 */
  double extent;        /* side of the square city in metres; 0 = 600 */
  double block;         /* block pitch incl. street, metres; 0 = 60 */
  double street;        /* street width, metres; 0 = 14 */
  int detail;           /* facade subdivision (windows per storey etc.), 1..8; 0 = 2 */
} gi_city_params;

/* Adds the city's geometry, materials and lights to b. */
gi_result gi_city_generate(const gi_city_params *p, gi_mesh_builder *b, gi_light *lights,
                           size_t max_lights, size_t *num_lights, gi_error_info *err);

/* Convenience: generates and builds the scene (name "city"), with the city's
 * sun and sky. opt may be NULL. */
gi_result gi_city_build(const gi_city_params *p, const gi_scene_options *opt, gi_scene **out,
                        gi_error_info *err);

/* About how many bytes generating, building and baking the city takes at
 * its peak (measured per triangle on 1-2 km cities, rounded up), and into
 * *triangles (may be NULL) about how many triangles it makes; 0 when p is
 * invalid. gi_city_generate refuses a city whose estimate exceeds the
 * machine's physical memory (GI_ERR_NOMEM, with the figures). */
double gi_city_bytes_estimate(const gi_city_params *p, double *triangles);

/* A sensible default viewpoint at street level (world coordinates). */
void gi_city_default_viewpoint(const gi_city_params *p, double at[3]);

#ifdef __cplusplus
}
#endif
#endif
