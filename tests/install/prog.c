/* prog.c: a program built against an installed libgi (by pkg-config and by
 * find_package(gi)). Bakes SCENE ("city" or a scene file) around X Y Z at
 * the low quality check-install.sh also gives gi-bake, prints the probe
 * there (irradiance, direct and indirect RGB) and writes the cascade to
 * OUT.vdb when given (OpenVDB through libgi, C++ underneath). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <gi/gi.h>

int main(int argc, char **argv) {
  if (argc != 5 && argc != 6) return fprintf(stderr, "usage: prog SCENE X Y Z [OUT.vdb]\n"), 2;
  double at[3] = {strtod(argv[2], NULL), strtod(argv[3], NULL), strtod(argv[4], NULL)};
  gi_scene_options so = {.threads = 2, .default_lights = 1};
  gi_quality q = {.levels = 3, .res = 8, .bounces = 1, .light_samples = 4, .probe_samples = 16, .threads = 2};
  gi_city_params city = {0};
  gi_scene *s = NULL;
  gi_cascade *c = NULL;
  gi_probe p;
  gi_error_info err = {0};
  gi_result r = strcmp(argv[1], "city") ? gi_scene_load(argv[1], &so, &s, &err) : gi_city_build(&city, &so, &s, &err);
  if (r == GI_OK) r = gi_cascade_bake(s, at, &q, &c, NULL, &err);
  if (r == GI_OK) r = gi_cascade_gather(c, at, 1, &p, NULL, &err);
  if (r == GI_OK && argc == 6) r = gi_cascade_write_vdb(c, argv[5], 0, &err);
  if (r != GI_OK) return fprintf(stderr, "prog: %s\n", err.msg[0] ? err.msg : gi_strerror(r)), 1;
  printf("%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", p.irradiance[0], p.irradiance[1], p.irradiance[2],
         p.direct[0], p.direct[1], p.direct[2], p.indirect[0], p.indirect[1], p.indirect[2]);
  gi_cascade_free(c);
  gi_scene_release(s);
  return 0;
}
