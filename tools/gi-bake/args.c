/* args.c: gi-bake's command line, parsed strictly.
 *
 * Design: every number goes through the tools' shared helpers
 * (tools/common/toolargs.h: one rule for integers, numbers and comma lists)
 * that check the whole string is a plain decimal, finite and within range,
 * and otherwise print "gi-bake: --opt: expected ..., got '...'" and make the
 * run exit 2. Each group of options has its own function (scene, quality,
 * lights, render, city); cli_parse only dispatches, then checks the
 * combinations. Values
 * are range-checked here, before any scene is loaded, so a typo never costs
 * a slow load; the core checks them again (it trusts no caller). Defaults
 * stay zero in gi_quality so the core resolves them in one place. */
#define _POSIX_C_SOURCE 200809L
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cli.h"
#include "toolargs.h"

#define MAX_POINTS ((size_t)1 << 24) /* the probe EXR holds at most 2^24 pixels */

enum {
  OPT_AT = 256, OPT_UP, OPT_LEVELS, OPT_RES, OPT_VOXEL, OPT_CONES, OPT_BOUNCES, OPT_SAMPLES,
  OPT_PROBE_SAMPLES, OPT_THREADS, OPT_EXR, OPT_HALF, OPT_VDB, OPT_VDB_FACES, OPT_JSON, OPT_PROBES,
  OPT_SUN, OPT_SKY, OPT_POINT, OPT_SPOT, OPT_NO_DEFAULT_LIGHTS, OPT_AO, OPT_CITY_EXTENT, OPT_CITY_SEED,
  OPT_CITY_DETAIL, OPT_EFFECT, OPT_RENDER, OPT_PNG, OPT_RENDER_SAMPLES, OPT_RENDER_STRIDE
};

static const struct option long_opts[] = {
    {"at", required_argument, NULL, OPT_AT},
    {"up", required_argument, NULL, OPT_UP},
    {"levels", required_argument, NULL, OPT_LEVELS},
    {"res", required_argument, NULL, OPT_RES},
    {"voxel", required_argument, NULL, OPT_VOXEL},
    {"cones", required_argument, NULL, OPT_CONES},
    {"bounces", required_argument, NULL, OPT_BOUNCES},
    {"samples", required_argument, NULL, OPT_SAMPLES},
    {"probe-samples", required_argument, NULL, OPT_PROBE_SAMPLES},
    {"threads", required_argument, NULL, OPT_THREADS},
    {"exr", required_argument, NULL, OPT_EXR},
    {"half", no_argument, NULL, OPT_HALF},
    {"vdb", required_argument, NULL, OPT_VDB},
    {"vdb-faces", no_argument, NULL, OPT_VDB_FACES},
    {"json", no_argument, NULL, OPT_JSON},
    {"probes", required_argument, NULL, OPT_PROBES},
    {"sun", required_argument, NULL, OPT_SUN},
    {"sky", required_argument, NULL, OPT_SKY},
    {"point", required_argument, NULL, OPT_POINT},
    {"spot", required_argument, NULL, OPT_SPOT},
    {"no-default-lights", no_argument, NULL, OPT_NO_DEFAULT_LIGHTS},
    {"ao", no_argument, NULL, OPT_AO},
    {"effect", required_argument, NULL, OPT_EFFECT},
    {"render", required_argument, NULL, OPT_RENDER},
    {"png", required_argument, NULL, OPT_PNG},
    {"render-samples", required_argument, NULL, OPT_RENDER_SAMPLES},
    {"render-stride", required_argument, NULL, OPT_RENDER_STRIDE},
    {"city-extent", required_argument, NULL, OPT_CITY_EXTENT},
    {"city-seed", required_argument, NULL, OPT_CITY_SEED},
    {"city-detail", required_argument, NULL, OPT_CITY_DETAIL},
    BATCH_LONG_OPTS,
    {"lightmap", required_argument, NULL, LM_OPT_OUT},
    {"uv-out", required_argument, NULL, LM_OPT_UV_OUT},
    {"texel", required_argument, NULL, LM_OPT_TEXEL},
    {"atlas", required_argument, NULL, LM_OPT_ATLAS},
    {"tile", required_argument, NULL, LM_OPT_TILE},
    {"own-charts", no_argument, NULL, LM_OPT_OWN_CHARTS},
    {"help", no_argument, NULL, 'h'},
    {"version", no_argument, NULL, 'V'},
    {NULL, 0, NULL, 0}};

static const char help_text[] =
    "Usage: gi-bake SCENE [options]\n"
    "       gi-bake merge [--exr OUT.exr] [--vdb OUT.vdb] SHARD.exr...\n"
    "Bakes global illumination around a viewpoint with cascaded voxel cone tracing\n"
    "and prints what it did. SCENE is a scene file (OBJ, PLY, glTF, 3DS, FBX) or the\n"
    "word 'city' for the embedded procedural city (use ./city for a file named city).\n"
    "\n"
    "Viewpoint and scene\n"
    "  --at X,Y,Z            viewpoint, world units (default: city street corner, or\n"
    "                        the centre of a file scene's bounds)\n"
    "  --up y|z              file scene's up axis (default y; OSM cities use z)\n"
    "  --probes FILE         extra gather points, one 'x y z' per line (blanks, a comma\n"
    "                        or both), '#' comments, a first line 'x,y,z' skipped;\n"
    "                        the probe EXR gets one pixel per point, viewpoint first\n"
    "\n"
    "Quality (defaults resolved by the core)\n"
    "  --levels N            cascade levels, 1..12 (default 6; more for a scene wider\n"
    "                        than 16 heights, see --voxel)\n"
    "  --res R               voxels per side per level, multiple of 4 in 8..256 (32)\n"
    "  --voxel S0            finest voxel size, world units (default: coarsest level\n"
    "                        spans the scene, at most 16 heights; a wider scene keeps\n"
    "                        that and adds levels until s0 is what a piece 4 heights\n"
    "                        across would get)\n"
    "  --cones N             diffuse cones per hemisphere: 4, 6, 8, 16, 32 (16)\n"
    "  --bounces N           voxel-to-voxel bounces, 0..8, 0 = none (default: from\n"
    "                        the albedo in range, 1..4; the effect plan says why)\n"
    "  --samples N           shadow rays per voxel for sky/area lights, 1..512 (16)\n"
    "  --probe-samples N     shadow rays per probe for sky/area lights, 1..8192 (256)\n"
    "  --ao                  also compute ambient occlusion at the probes (off)\n"
    "  --effect NAME=on|off|auto  override the effect plan for one effect; NAME is\n"
    "                        sun, local_lights, sky, emissive, bounce, specular or ao\n"
    "                        (repeatable; default auto: decided from the scene)\n"
    "  --threads N           worker threads, 0 = all cores (0)\n"
    "\n"
    "Lights (added to the scene's own; repeatable, at most 64)\n"
    "  --sun DX,DY,DZ,R,G,B  directional light: direction the light travels (need not\n"
    "                        be unit length), irradiance on a facing surface (W/m^2)\n"
    "  --sky R,G,B           uniform sky radiance (W/m^2/sr)\n"
    "  --point X,Y,Z,R,G,B   point light: position (world units), intensity (W/sr)\n"
    "  --spot X,Y,Z,DX,DY,DZ,INNER,OUTER,R,G,B\n"
    "                        spot light: position, direction it shines, full cone\n"
    "                        angles in degrees (full intensity inside INNER, none\n"
    "                        outside OUTER, 0 < INNER <= OUTER < 180), intensity (W/sr)\n"
    "  --no-default-lights   do not add a sun and sky to a scene with no lights and\n"
    "                        no emitters (added by default)\n"
    "\n"
    "Procedural city (SCENE = city only)\n"
    "  --city-extent M       side of the square city, metres, up to 20000 (600);\n"
    "                        about 240 B per triangle, 0.35 triangles per m^2 at\n"
    "                        detail 2: refused past the machine's memory\n"
    "  --city-seed N         layout seed, unsigned 64-bit, 0 = default (1)\n"
    "  --city-detail N       facade subdivision, 1..8 (2)\n"
    "\n"
    BATCH_HELP
    "Outputs (files are written to a temporary name, then renamed)\n"
    "  --exr OUT.exr         probe EXR: R,G,B, irradiance/direct/indirect.R,G,B, ao.Y,\n"
    "                        sh.L00.R .. sh.L22.B (one pixel per probe)\n"
    "  --half                store the EXR as half floats (default float; not with\n"
    "                        --grid, whose shards must merge losslessly)\n"
    "  --vdb OUT.vdb         cascade snapshot: L<d>_density, L<d>_Cd, L<d>_albedo,\n"
    "                        L<d>_normal per level, plain density/Cd for level 0\n"
    "  --vdb-faces           add the six per-face radiance grids L<d>_face_px..\n"
    "  --json                print one JSON object instead of the summary\n"
    "\n"
    "Lightmap (instead of the probes: the scene's surfaces baked into atlases)\n"
    "  --lightmap OUT.exr    multilayer EXR atlas: R,G,B = albedo x irradiance / pi,\n"
    "                        irradiance/direct/indirect.R,G,B, valid.Y; several\n"
    "                        atlases go to OUT.0001.exr, OUT.0002.exr ... (an earlier\n"
    "                        run's atlases under OUT that this run did not write are\n"
    "                        removed); refused (exit 2) when the atlases would take\n"
    "                        more than the machine's memory (80 bytes per texel and\n"
    "                        working copies)\n"
    "  --region X0,Y0,Z0,X1,Y1,Z1  only triangles whose centre is in this box\n"
    "                        (default: the whole scene; the same option as --grid's)\n"
    "  --texel S             texel size, world units (default 0.25); unused with\n"
    "                        the scene's own lightmap UVs (gi.texel: their mean)\n"
    "  --atlas N             atlas side in texels, 16..16384 (default 2048)\n"
    "  --tile S              bake the region in tiles of side S, world units, one\n"
    "                        cascade each, every texel from its own tile's (default\n"
    "                        0.8 x the coarsest level, smaller until each tile's\n"
    "                        cascade holds its texels: one tile for most scenes).\n"
    "                        An S whose tile's cascade cannot hold that tile's\n"
    "                        texels is refused (exit 2, naming the coarsest level's\n"
    "                        side); an S past the region's size makes one tile.\n"
    "                        Texels far from their tile's centre read its coarse\n"
    "                        voxels: Munich's ground 500 m from its centre read 0%,\n"
    "                        39%, 50%, 69%, 84% of the reference's indirect light\n"
    "                        with one tile, 600, 300, 150, 100 m (21-48 s at --texel 2)\n"
    "  --uv-out OUT.glb      the lightmap's triangles as glTF 2.0, lightmap UVs in\n"
    "                        TEXCOORD_1, one mesh per atlas; Y up as glTF defines it\n"
    "                        (--up z turns (x, y, z) into (x, z, -y))\n"
    "  --own-charts          make charts even when the scene has lightmap UVs of its\n"
    "                        own (a second UV set, which must lie in [0, 1])\n"
    "\n"
    "Pictures (the view from the cascade beside the same view path-traced)\n"
    "  --render CAMERA       a Mitsuba XML file's perspective sensor (0.6 or 3:\n"
    "                        to_world, fov or focal_length, its film's aspect at\n"
    "                        256 pixels across), or X,Y,Z,TX,TY,TZ,FOV,W,H: eye, target,\n"
    "                        fov in degrees across the smaller side, pixels\n"
    "                        (up = the scene's up axis; looking straight down\n"
    "                        or up, north: +y for z up, -z for y up)\n"
    "  --png OUT.png         cone-traced | path-traced | error side by side (needs\n"
    "                        --render); with --render, --exr gets the images\n"
    "                        (R,G,B cone-traced, path.R/G/B, error.Y) instead of probes\n"
    "  --render-samples N    paths per pixel of the path-traced view, 1..65536 (64)\n"
    "  --render-stride N     the cascade's view gathers indirect light and samples the\n"
    "                        sky and emitters at every Nth pixel of every Nth row and\n"
    "                        mixes them between those on a pixel's own surface;\n"
    "                        1 = at every pixel, 1..16 (4)\n"
    "  -h, --help            this text;  -V, --version  the version\n"
    "\n"
    "Environment: GI_CPU_PATH=baseline|x86-64-v3|auto picks the cone march's build\n"
    "(auto, the default: x86-64-v3 when the CPU has it); another value is exit 2.\n"
    "\n"
    "Exit status: 0 success, 1 the scene, bake or an output failed, 2 bad arguments.\n"
    "\n"
    "Examples\n"
    "  gi-bake city --exr out/city-probe.exr --vdb out/city-cascades.vdb\n"
    "  gi-bake cornell-box.obj --at 278,273,279.6 --bounces 3 --json\n"
    "  gi-bake munich.obj --up z --grid 4 --above-ground 2 --vdb probes.vdb\n";

static ta_ctx ta = TA_CTX("gi-bake");

/* A light colour: three finite values in [0, GI_MAX_LIGHT_VALUE] (gi_scene.h says why). */
static int colour_ok(const double c[3]) {
  for (int k = 0; k < 3; k++)
    if (!(c[k] >= 0) || c[k] > GI_MAX_LIGHT_VALUE) return 0;
  return 1;
}

/* The error of a colour colour_ok refused; what names it (intensity, irradiance). */
static int colour_fail(const char *opt, const char *what, const char *arg) {
  return ta_fail(&ta, opt, "%s R,G,B must be finite, >= 0 and at most 1e20, got '%s'", what, arg);
}

/* The unit vector along d[0..2] into out; 0 when d is zero or not finite.
 * Scaled by its largest component first: the length of (0, -1e300, 0)
 * overflowed and a finite, non-zero direction was refused as neither. */
static int unit_direction(const double d[3], float out[3]) {
  double m = fmax(fabs(d[0]), fmax(fabs(d[1]), fabs(d[2])));
  if (!(m > 0) || !isfinite(m)) return 0;
  double e[3] = {d[0] / m, d[1] / m, d[2] / m}, len = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
  for (int k = 0; k < 3; k++) out[k] = (float)(e[k] / len);
  return 1;
}

/* A lamp's position within 1e30 of the origin (the server's bound for a
 * point): past float's range its direction went NaN inside the bake. */
static int position_ok(const char *opt, const double v[3], const char *arg) {
  for (int k = 0; k < 3; k++)
    if (!(fabs(v[k]) <= 1e30)) return ta_fail(&ta, opt, "position X,Y,Z must be within 1e30 of the origin, got '%s'", arg);
  return 0;
}

/* --spot X,Y,Z,DX,DY,DZ,INNER,OUTER,R,G,B */
static int parse_spot(const char *opt, const char *arg, gi_light *l) {
  double v[11];
  int rc = ta_doubles(&ta, opt, "eleven finite numbers X,Y,Z,DX,DY,DZ,INNER,OUTER,R,G,B", arg, 11, v);
  if (rc || (rc = position_ok(opt, v, arg))) return rc;
  if (!unit_direction(v + 3, l->direction))
    return ta_fail(&ta, opt, "direction DX,DY,DZ must be a non-zero finite vector, got '%s'", arg);
  if (!(v[6] > 0 && v[6] <= v[7] && v[7] < 180))
    return ta_fail(&ta, opt, "cone angles must satisfy 0 < INNER <= OUTER < 180 degrees, got '%s'", arg);
  if (!colour_ok(v + 8)) return colour_fail(opt, "intensity", arg);
  l->type = GI_LIGHT_SPOT;
  for (int k = 0; k < 3; k++) {
    l->position[k] = v[k];
    l->color[k] = (float)v[8 + k];
  }
  const double deg = 3.14159265358979323846 / 180.0;
  l->cos_inner = (float)cos(0.5 * v[6] * deg);
  l->cos_outer = (float)cos(0.5 * v[7] * deg);
  return 0;
}

/* --sun DX,DY,DZ,R,G,B */
static int parse_sun(const char *opt, const char *arg, gi_light *l) {
  double v[6];
  int rc = ta_doubles(&ta, opt, "six finite numbers DX,DY,DZ,R,G,B", arg, 6, v);
  if (rc) return rc;
  if (!unit_direction(v, l->direction))
    return ta_fail(&ta, opt, "direction DX,DY,DZ must be a non-zero finite vector, got '%s'", arg);
  if (!colour_ok(v + 3)) return colour_fail(opt, "irradiance", arg);
  l->type = GI_LIGHT_SUN;
  for (int k = 0; k < 3; k++) l->color[k] = (float)v[3 + k];
  return 0;
}

/* --sky R,G,B */
static int parse_sky(const char *opt, const char *arg, gi_light *l) {
  static const char what[] = "three finite numbers R,G,B in 0..1e20";
  double v[3];
  int rc = ta_doubles(&ta, opt, what, arg, 3, v);
  if (rc) return rc;
  if (!colour_ok(v)) return ta_fail(&ta, opt, "expected %s, got '%s'", what, arg);
  l->type = GI_LIGHT_SKY;
  for (int k = 0; k < 3; k++) l->color[k] = (float)v[k];
  return 0;
}

/* --point X,Y,Z,R,G,B */
static int parse_point(const char *opt, const char *arg, gi_light *l) {
  double v[6];
  int rc = ta_doubles(&ta, opt, "six finite numbers X,Y,Z,R,G,B", arg, 6, v);
  if (rc || (rc = position_ok(opt, v, arg))) return rc;
  if (!colour_ok(v + 3)) return colour_fail(opt, "intensity", arg);
  l->type = GI_LIGHT_POINT;
  for (int k = 0; k < 3; k++) {
    l->position[k] = v[k];
    l->color[k] = (float)v[3 + k];
  }
  return 0;
}

/* --sun, --sky, --point, --spot: one more light. */
static int add_light(cli_opts *o, int c, const char *arg) {
  const char *opt = c == OPT_SUN ? "--sun" : c == OPT_SKY ? "--sky" : c == OPT_POINT ? "--point" : "--spot";
  if (o->num_lights >= CLI_MAX_LIGHTS)
    return ta_fail(&ta, opt, "at most %d lights can be given on the command line", CLI_MAX_LIGHTS);
  gi_light l;
  memset(&l, 0, sizeof l);
  int rc = c == OPT_SUN ? parse_sun(opt, arg, &l)
           : c == OPT_SKY ? parse_sky(opt, arg, &l)
           : c == OPT_POINT ? parse_point(opt, arg, &l)
                            : parse_spot(opt, arg, &l);
  if (rc) return rc;
  o->lights[o->num_lights++] = l;
  return 0;
}

/* --effect NAME=on|off|auto */
static int parse_effect(cli_opts *o, const char *arg) {
  const char *eq = strchr(arg, '=');
  char name[32];
  size_t len = eq ? (size_t)(eq - arg) : 0;
  if (!eq || len == 0 || len >= sizeof name)
    return ta_fail(&ta, "--effect", "expected NAME=on|off|auto, got '%s'", arg);
  memcpy(name, arg, len);
  name[len] = '\0';
  int id = gi_effect_from_name(name);
  if (id < 0)
    return ta_fail(&ta, "--effect", "unknown effect '%s' (sun, local_lights, sky, emissive, bounce, specular, ao)",
                   name);
  /* Repeatable for different effects; the same one twice silently took the last. */
  if (o->effect_given[id]) return ta_fail(&ta, "--effect", "'%s' given twice", name);
  o->effect_given[id] = 1;
  if (!strcmp(eq + 1, "on")) o->q.effects[id] = GI_FX_ON;
  else if (!strcmp(eq + 1, "off")) o->q.effects[id] = GI_FX_OFF;
  else if (!strcmp(eq + 1, "auto")) o->q.effects[id] = GI_FX_AUTO;
  else return ta_fail(&ta, "--effect", "expected on, off or auto after '%s=', got '%s'", name, eq + 1);
  return 0;
}

/* --render CAMERA: a Mitsuba .xml sensor or X,Y,Z,TX,TY,TZ,FOV,W,H. */
static int parse_render(cli_opts *o, const char *arg) {
  double c[9];
  const char *dot = strrchr(arg, '.');
  if (dot && !strcmp(dot, ".xml")) {
    gi_error_info e = {0};
    if (gi_camera_from_mitsuba(arg, &o->cam, &e) != GI_OK) return ta_fail(&ta, "--render", "%s", e.msg);
    gi_camera_fit(&o->cam, 256); /* the film's aspect; its longer side 256 pixels */
  } else if (ta_parse_doubles(arg, c, 9) == TA_OK) {
    memcpy(o->cam.eye, c, sizeof(double[3]));
    memcpy(o->cam.target, c + 3, sizeof(double[3]));
    o->cam.fov_deg = c[6];
    if (c[7] != floor(c[7]) || c[8] != floor(c[8]) || !(c[7] >= 1 && c[7] <= 4096 && c[8] >= 1 && c[8] <= 4096))
      return ta_fail(&ta, "--render", "W and H must be whole numbers of pixels in 1..4096, got '%s'", arg);
    o->cam.width = (int)c[7], o->cam.height = (int)c[8];
    o->cam_up_from_scene = 1;
  } else {
    return ta_fail(&ta, "--render", "expected a Mitsuba .xml file or X,Y,Z,TX,TY,TZ,FOV,W,H, got '%s'", arg);
  }
  o->render = 1;
  return 0;
}

/* --at, --up, --probes */
static int scene_option(cli_opts *o, int c, const char *arg) {
  int rc = 0;
  if (c == OPT_AT) {
    if (!(rc = ta_triple(&ta, "--at", arg, o->at))) o->have_at = 1;
  } else if (c == OPT_UP) {
    if (!strcmp(arg, "y") || !strcmp(arg, "Y")) o->up = GI_UP_Y;
    else if (!strcmp(arg, "z") || !strcmp(arg, "Z")) o->up = GI_UP_Z;
    else rc = ta_fail(&ta, "--up", "expected y or z, got '%s'", arg);
  } else {
    o->probes_file = arg;
  }
  return rc;
}

/* The quality knobs: --levels .. --threads, --ao, --effect. */
static int quality_option(cli_opts *o, int c, const char *arg) {
  gi_quality *q = &o->q;
  int rc = 0;
  switch (c) {
  case OPT_LEVELS: return ta_int(&ta, "--levels", NULL, arg, 1, GI_MAX_LEVELS, &q->levels);
  case OPT_RES: {
    static const char what[] = "a multiple of 4 in 8..256";
    if (!(rc = ta_int(&ta, "--res", what, arg, 8, 256, &q->res)) && q->res % 4)
      rc = ta_fail(&ta, "--res", "expected %s, got '%s'", what, arg);
    return rc;
  }
  case OPT_VOXEL: return ta_double(&ta, "--voxel", "a voxel size in (0, 1e7] (the server's range)", arg, 0, 1e7, &q->voxel0);
  case OPT_CONES: {
    static const char what[] = "4, 6, 8, 16 or 32";
    int v = 0;
    if (!(rc = ta_int(&ta, "--cones", what, arg, 4, 32, &v)) && v != 4 && v != 6 && v != 8 && v != 16 && v != 32)
      rc = ta_fail(&ta, "--cones", "expected %s, got '%s'", what, arg);
    if (!rc) q->cones = v;
    return rc;
  }
  case OPT_BOUNCES:
    if (!(rc = ta_int(&ta, "--bounces", NULL, arg, 0, 8, &q->bounces)) && q->bounces == 0)
      q->bounces = -1; /* the core reads 0 as "default" */
    return rc;
  case OPT_SAMPLES: return ta_int(&ta, "--samples", NULL, arg, 1, 512, &q->light_samples);
  case OPT_PROBE_SAMPLES: return ta_int(&ta, "--probe-samples", NULL, arg, 1, 8192, &q->probe_samples);
  case OPT_THREADS:
    return ta_int(&ta, "--threads", "an integer in 0..256 (0 = all cores)", arg, 0, 256, &q->threads);
  case OPT_AO: q->ao = 1; return 0;
  default: return parse_effect(o, arg);
  }
}

/* --city-extent, --city-seed, --city-detail */
static int city_option(cli_opts *o, int c, const char *arg) {
  int rc;
  if (c == OPT_CITY_EXTENT)
    rc = ta_double(&ta, "--city-extent", "metres in (0, 20000]", arg, 0, 20000, &o->city.extent);
  else if (c == OPT_CITY_SEED)
    rc = ta_u64(&ta, "--city-seed", NULL, arg, &o->city.seed);
  else
    rc = ta_int(&ta, "--city-detail", NULL, arg, 1, 8, &o->city.detail);
  if (!rc) o->city_opts_given = 1;
  return rc;
}

/* One option from getopt_long. Returns 0, -1 (--help/--version printed) or an exit code. */
static int apply_option(cli_opts *o, int c, const char *arg, char **argv) {
  switch (c) {
  case 'h': fputs(help_text, stdout); return -1;
  case 'V': printf("gi-bake %s\ncpu path: %s\n", ta_version(), gi_cpu_path()); return -1;
  case OPT_AT: case OPT_UP: case OPT_PROBES: return scene_option(o, c, arg);
  case OPT_LEVELS: case OPT_RES: case OPT_VOXEL: case OPT_CONES: case OPT_BOUNCES: case OPT_SAMPLES:
  case OPT_PROBE_SAMPLES: case OPT_THREADS: case OPT_AO: case OPT_EFFECT:
    return quality_option(o, c, arg);
  case OPT_SUN: case OPT_SKY: case OPT_POINT: case OPT_SPOT: return add_light(o, c, arg);
  case OPT_NO_DEFAULT_LIGHTS: o->no_default_lights = 1; return 0;
  case OPT_EXR: o->exr = arg; return 0;
  case OPT_HALF: o->half = 1; return 0;
  case OPT_VDB: o->vdb = arg; return 0;
  case OPT_VDB_FACES: o->vdb_faces = 1; return 0;
  case OPT_JSON: o->json = 1; return 0;
  case OPT_RENDER: return parse_render(o, arg);
  case OPT_PNG: o->png = arg; return 0;
  case OPT_RENDER_SAMPLES: return ta_int(&ta, "--render-samples", NULL, arg, 1, 65536, &o->render_spp);
  case OPT_RENDER_STRIDE:
    return ta_int(&ta, "--render-stride", NULL, arg, 1, GI_RENDER_MAX_STRIDE, &o->render_stride);
  case OPT_CITY_EXTENT: case OPT_CITY_SEED: case OPT_CITY_DETAIL: return city_option(o, c, arg);
  case OPT_GRID: case OPT_REGION: case OPT_ABOVE_GROUND: case OPT_SHARD: case OPT_RESUME: case OPT_MANIFEST:
  case OPT_MAX_TILES:
    return batch_option(&ta, &o->batch, c, arg);
  case LM_OPT_OUT: case LM_OPT_UV_OUT: case LM_OPT_TEXEL: case LM_OPT_ATLAS: case LM_OPT_TILE: case LM_OPT_OWN_CHARTS:
    return lightmap_option(o, c, arg);
  default: return ta_getopt_fail(&ta, c, argv, long_opts);
  }
}

/* The one SCENE operand, after the options. */
static int take_scene(int argc, char **argv, cli_opts *o) {
  if (optind >= argc) return ta_fail(&ta, NULL, "missing SCENE (a scene file or 'city')");
  if (optind + 1 < argc)
    return ta_fail(&ta, NULL, "one SCENE expected, got '%s' and '%s'", argv[optind], argv[optind + 1]);
  o->scene = argv[optind];
  o->is_city = !strcmp(o->scene, "city");
  return 0;
}

/* The --render camera, checked with the up axis it will most likely get. */
static int check_render_camera(const cli_opts *o) {
  gi_camera cam = o->cam;
  gi_error_info e = {0};
  /* The up axis is known only after loading, where it is set again. */
  if (o->cam_up_from_scene) cli_render_up(&cam, o->up == GI_UP_Z);
  if (gi_camera_validate(&cam, &e) != GI_OK) return ta_fail(&ta, "--render", "%s", e.msg);
  return 0;
}

/* Options that need or exclude each other; then the files, before any slow work. */
static int check_combinations(cli_opts *o) {
  int rc;
  if (o->is_city && o->up == GI_UP_Z) return ta_fail(&ta, "--up", "the procedural city is always Y-up");
  if (o->q.bounces < 0 && o->q.effects[GI_FX_BOUNCE] == GI_FX_ON)
    return ta_fail(&ta, "--bounces", "0 (none) contradicts --effect bounce=on: give one or the other");
  if (!o->is_city && o->city_opts_given)
    return ta_fail(&ta, NULL, "--city-extent, --city-seed and --city-detail apply only to the scene 'city'");
  if (o->half && !o->exr && !o->lm.out) return ta_fail(&ta, "--half", "needs --exr or --lightmap");
  if ((rc = lightmap_check(o))) return rc;
  if (o->png && !o->render) return ta_fail(&ta, "--png", "needs --render");
  if (o->render_stride && !o->render) return ta_fail(&ta, "--render-stride", "needs --render");
  if (o->render_spp && !o->render) return ta_fail(&ta, "--render-samples", "needs --render");
  if (o->render && !o->png && !o->exr) return ta_fail(&ta, "--render", "needs --png or --exr for the pictures");
  if (o->render && (rc = check_render_camera(o))) return rc;
  if (o->png && (rc = ta_check_output(&ta, "--png", &o->png))) return rc;
  if (o->vdb_faces && !o->vdb) return ta_fail(&ta, "--vdb-faces", "needs --vdb");
  if (o->exr && (rc = ta_check_output(&ta, "--exr", &o->exr))) return rc;
  if (o->vdb && (rc = ta_check_output(&ta, "--vdb", &o->vdb))) return rc;
  if ((rc = batch_check(&ta, o))) return rc;
  /* An output renamed over an input would destroy it (after reading it). */
  if ((!o->is_city && (rc = ta_check_outputs_spare(&ta, "scene file", o->scene))) ||
      (rc = ta_check_outputs_spare(&ta, "--probes file", o->probes_file)))
    return rc;
  /* The viewpoint takes one of the probe EXR's pixels. */
  if (o->probes_file &&
      (rc = ta_read_points(&ta, "--probes", o->probes_file, MAX_POINTS - 1, &o->probes, &o->num_probes)))
    return rc;
  return 0;
}

int cli_parse(int argc, char **argv, cli_opts *o) {
  memset(o, 0, sizeof *o);
  opterr = 0; /* our messages, with our program name */
  int c, rc;
  /* Lights and effects repeat; every other value is given at most once. */
  static const int repeatable[] = {OPT_SUN, OPT_SKY, OPT_POINT, OPT_SPOT, OPT_EFFECT, 0};
  unsigned char given[sizeof long_opts / sizeof long_opts[0]] = {0};
  while ((c = getopt_long(argc, argv, ":hV", long_opts, NULL)) != -1)
    if ((rc = ta_once(&ta, long_opts, c, repeatable, given)) || (rc = apply_option(o, c, optarg, argv)))
      return rc;
  if ((rc = take_scene(argc, argv, o))) return rc;
  return check_combinations(o);
}

void cli_opts_fini(cli_opts *o) {
  free(o->probes);
  o->probes = NULL;
}
