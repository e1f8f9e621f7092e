/* test_render.c: camera views against closed-form answers.
 *
 * A plane of albedo a under a sun of irradiance E at 60 degrees, seen from
 * above: every pixel that sees the plane shows L = a E cos60 / pi, in the
 * cone-traced view (one shadow ray, nothing to bounce) and in the
 * path-traced one (the continuation rays all escape), exactly up to float
 * rounding. The Cornell box's Mitsuba sensor is read as published (shared
 * scene; skips loudly when absent). Bad cameras name the field. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"
#include "answer/answer.h"
#include "base/internal.h"
#include "trace/trace.h"

static void test_plane_under_sun(void **state) {
  const double c60 = 0.5, a = 0.5, E = 3.0;
  gi_scene *s = tu_sunlit_plane(a, E, 100);
  gi_error_info err = {0};
  gi_quality q = {.levels = 2, .res = 16, .voxel0 = 1};
  gi_cascade *c = NULL;
  double at[3] = {0, 1, 0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  gi_camera cam = {.eye = {0, 5, 0}, .target = {0, 0, 0}, .up = {0, 0, 1}, .fov_deg = 40, .width = 16, .height = 12};
  float cone[16 * 12 * 3], path[16 * 12 * 3];
  assert_int_equal(gi_cascade_render(c, &cam, 0, 0, cone, NULL, &err), GI_OK);
  assert_int_equal(gi_reference_render(s, &cam, 4, 1, 0, path, NULL, &err), GI_OK);
  double want = a * E * c60 / 3.14159265358979;
  printf("plane: cone %.6f, path %.6f, exact %.6f\n", cone[0], path[0], want);
  for (int i = 0; i < 16 * 12 * 3; i++) {
    assert_true(fabs(path[i] - want) < 1e-5);
    /* The cone view adds what the voxels bounce back: a flat plane has nothing above it. */
    assert_true(fabs(cone[i] - want) < 1e-3 * want);
  }
  /* The same plane from 1e6 units off, at 45 degrees, the view narrowed
   * to a 20-unit patch: the path tracer's hits, rebuilt as eye + t w in
   * float, lay up to 0.06 off the plane, and those below it read 0. */
  gi_camera far = cam;
  far.eye[0] = 0, far.eye[1] = 7e5, far.eye[2] = -7e5;
  far.up[0] = 0, far.up[1] = 1, far.up[2] = 0;
  far.fov_deg = 2 * atan(10 / 9.9e5) * 180 / 3.14159265358979;
  assert_int_equal(gi_reference_render(s, &far, 4, 1, 0, path, NULL, &err), GI_OK);
  double worst = 0;
  for (int i = 0; i < 16 * 12 * 3; i++) worst = fmax(worst, fabs(path[i] - want) / want);
  printf("plane seen from 1e6 off: path tracer's largest relative error %.2g\n", worst);
  assert_true(worst < 1e-4);
  /* A PNG of it: written atomically, non-empty. */
  const char *png = tu_write_file("view.png", "", 0);
  assert_int_equal(gi_image_write_png(png, cone, 16, 12, 1.0f, &err), GI_OK);
  FILE *f = fopen(png, "rb");
  unsigned char sig[8] = {0};
  assert_non_null(f);
  assert_int_equal(fread(sig, 1, 8, f), 8);
  fclose(f);
  assert_memory_equal(sig, "\x89PNG\r\n\x1a\n", 8);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* A camera standing on the floor sees the room as one a hair above it
 * does, in both views: they read 0.21x and 0.20x of it, black wherever
 * they looked up (their first rays met the floor itself at t = 0, from
 * its unlit side: the room's floor faces down). */
static void test_camera_on_floor(void **state) {
  (void)state;
  gi_scene *s = tu_lit_room(0.7f);
  gi_error_info err = {0};
  gi_quality q = {.levels = 3, .res = 16, .voxel0 = 0.1};
  gi_cascade *c = NULL;
  double at[3] = {0.5, 0.5, 0.5};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  enum { W = 12, H = 8 };
  double mean[2][2] = {{0}};
  for (int k = 0; k < 2; k++) {
    gi_camera cam = {.eye = {0.5, k ? 1e-3 : 0, 0.5}, .target = {-1.5, 1.2, -1.5}, .up = {0, 1, 0}, .fov_deg = 60,
                     .width = W, .height = H};
    float cone[W * H * 3], path[W * H * 3];
    assert_int_equal(gi_cascade_render(c, &cam, 0, 0, cone, NULL, &err), GI_OK);
    assert_int_equal(gi_reference_render(s, &cam, 16, 1, 0, path, NULL, &err), GI_OK);
    for (int i = 0; i < W * H * 3; i++) mean[k][0] += cone[i] / (W * H * 3), mean[k][1] += path[i] / (W * H * 3);
  }
  printf("camera on the floor: cone %.5f path %.5f; 1 mm up: cone %.5f path %.5f\n", mean[0][0], mean[0][1],
         mean[1][0], mean[1][1]);
  for (int v = 0; v < 2; v++) {
    assert_true(mean[1][v] > 0);
    assert_true(fabs(mean[0][v] - mean[1][v]) <= 0.05 * mean[1][v]);
  }
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* A view square into a room's far half: its corner pixels' rays meet the
 * ceiling exactly on its edge with a side wall. Their point lay on both
 * planes, so every shadow ray left from the wall's plane and met it at
 * t = 0: the corners had no direct light at all (0 against 0.09-0.35
 * around them and 0.96 in the path tracer). */
static void test_edge_pixels(void **state) {
  (void)state;
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.7f, 0.7f, 0.7f}, .roughness = 1};
  const double lo[3] = {-1, 0, -1}, hi[3] = {1, 2, 1};
  gi_mesh_builder_add_box(b, lo, hi, gi_mesh_builder_add_material(b, &m));
  gi_light l = {.type = GI_LIGHT_POINT, .color = {5, 5, 5}, .position = {0, 1.8, 0}};
  gi_scene *s = tu_build(b, "edge-room", &l, 1);
  gi_error_info err = {0};
  gi_quality q = {.levels = 3, .res = 16, .bounces = 0, .effects = {[GI_FX_BOUNCE] = GI_FX_OFF}};
  gi_cascade *c = NULL;
  double at[3] = {0, 1, 0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  enum { W = 16 };
  gi_camera cam = {.eye = {0, 1, 0.9}, .target = {0, 1, -1}, .up = {0, 1, 0}, .fov_deg = 60, .width = W, .height = W};
  float cone[W * W * 3], path[W * W * 3];
  assert_int_equal(gi_cascade_render(c, &cam, 0, 0, cone, NULL, &err), GI_OK);
  assert_int_equal(gi_reference_render(s, &cam, 256, 1, 0, path, NULL, &err), GI_OK);
  const int corner[4] = {0, W - 1, W * (W - 1), W * W - 1};
  for (int i = 0; i < 4; i++) {
    float cv = cone[3 * corner[i]], pv = path[3 * corner[i]];
    printf("edge pixel %d: cone %.4f, path %.4f\n", corner[i], cv, pv);
    /* Direct light only in the cone view, all light in the path tracer's. */
    assert_true(cv > 0.05f && cv <= pv);
  }
  gi_cascade_free(c);
  gi_scene_release(s);
}

static void test_mitsuba_camera(void **state) {
  TU_SKIP_IF_NO_SCENE(path, "cornell-box/cbox-mitsuba.xml");
  gi_camera cam = {0};
  gi_error_info err = {0};
  assert_int_equal(gi_camera_from_mitsuba(path, &cam, &err), GI_OK);
  printf("cbox camera: eye %g %g %g, target %g %g %g, up %g %g %g, fov %g\n", cam.eye[0], cam.eye[1], cam.eye[2],
         cam.target[0], cam.target[1], cam.target[2], cam.up[0], cam.up[1], cam.up[2], cam.fov_deg);
  assert_true(cam.eye[0] == 278 && cam.eye[1] == 273 && cam.eye[2] == -800);
  assert_true(cam.target[2] == -799 && cam.up[1] == 1 && cam.up[0] == 0);
  assert_true(fabs(cam.fov_deg - 39.3077) < 1e-9);
  /* Its film is "$res" x "$res", with <default name="res" value="256"/>. */
  assert_int_equal(cam.width, 256);
  assert_int_equal(cam.height, 256);
}

/* Reads XML text as a Mitsuba sensor; returns the result, err filled. */
static gi_result mitsuba_text(const char *xml, gi_camera *cam, gi_error_info *err) {
  const char *path = tu_write_file("sensor.xml", xml, strlen(xml));
  memset(cam, 0, sizeof *cam);
  memset(err, 0, sizeof *err);
  return gi_camera_from_mitsuba(path, cam, err);
}

/* The unit view direction and up of cam (up made square to the view). */
static void cam_axes(const gi_camera *cam, double fwd[3], double up[3]) {
  double l = 0, d = 0;
  for (int k = 0; k < 3; k++) fwd[k] = cam->target[k] - cam->eye[k], l += fwd[k] * fwd[k];
  for (int k = 0; k < 3; k++) fwd[k] /= sqrt(l), d += cam->up[k] * fwd[k];
  l = 0;
  for (int k = 0; k < 3; k++) up[k] = cam->up[k] - d * fwd[k], l += up[k] * up[k];
  for (int k = 0; k < 3; k++) up[k] /= sqrt(l);
}

static void assert_vec(const double *got, double x, double y, double z, double tol) {
  printf("  (%.9f, %.9f, %.9f) want (%g, %g, %g)\n", got[0], got[1], got[2], x, y, z);
  assert_true(fabs(got[0] - x) <= tol && fabs(got[1] - y) <= tol && fabs(got[2] - z) <= tol);
}

static double deg(double rad) { return rad * 180 / 3.14159265358979323846; }
static double rad(double deg) { return deg * 3.14159265358979323846 / 180; }

/* Published scenes write their sensors in Mitsuba 0.6 and 3 syntax, by a
 * matrix, a lookat or a chain of transforms, with a fov along x, y or the
 * diagonal, or a focal length: each reads as Mitsuba places the camera. */
static void test_mitsuba_sensor_forms(void **state) {
  gi_camera cam, cam2;
  gi_error_info err;
  double f[3], u[3], f2[3], u2[3];
  /* 0.6, as most published scenes: a matrix (x axis = the image's left), fov along x by default. */
  const char *v06 = "<?xml version=\"1.0\"?>\n<scene version=\"0.6.0\">\n <sensor type=\"perspective\">\n"
                    "  <float name=\"fov\" value=\"19.5\"/>\n  <transform name=\"toWorld\">\n"
                    "   <matrix value=\"-1 0 0 0 0 1 0 1 0 0 -1 6.8 0 0 0 1\"/>\n  </transform>\n"
                    "  <sampler type=\"independent\"><integer name=\"sampleCount\" value=\"64\"/></sampler>\n"
                    "  <film type=\"ldrfilm\"><integer name=\"width\" value=\"1024\"/>"
                    "<integer name=\"height\" value=\"1024\"/></film>\n </sensor>\n</scene>\n";
  assert_int_equal(mitsuba_text(v06, &cam, &err), GI_OK);
  cam_axes(&cam, f, u);
  assert_vec(cam.eye, 0, 1, 6.8, 1e-12);
  assert_vec(f, 0, 0, -1, 1e-12);
  assert_vec(u, 0, 1, 0, 1e-12);
  assert_true(cam.fov_deg == 19.5 && cam.width == 1024 && cam.height == 1024);
  /* The same camera as a 0.6 lookAt: the same view (the matrix's x axis is up x forward). */
  const char *look = "<scene version=\"0.6.0\"><sensor type=\"perspective\"><string name=\"fovAxis\" value=\"smaller\"/>"
                     "<float name=\"fov\" value=\"19.5\"/><transform name=\"toWorld\"><lookAt origin=\"0, 1, 6.8\" "
                     "target=\"0,1,5.8\" up=\"0 1 0\"/></transform></sensor></scene>";
  assert_int_equal(mitsuba_text(look, &cam2, &err), GI_OK);
  cam_axes(&cam2, f2, u2);
  assert_vec(f2, f[0], f[1], f[2], 1e-12);
  assert_vec(u2, u[0], u[1], u[2], 1e-12);
  /* No film: Mitsuba's 768 x 576. */
  assert_true(cam2.width == 768 && cam2.height == 576);
  /* Mitsuba 3 with <default> values, a fov along x (its default) on a 16:9 film, and a lookat
   * turned 90 degrees about y and moved: forward +z turns to +x, the eye goes to (1, 2, 3). */
  const char *v3 = "<scene version=\"3.0.0\">\n<default name=\"fov\" value=\"60\"/>\n"
                   "<default name=\"w\" value=\"1920\"/><default name=\"h\" value=\"1080\"/>\n"
                   "<!-- <sensor type=\"orthographic\"> an old camera, commented out </sensor> -->\n"
                   "<sensor type=\"perspective\"><float name=\"fov\" value=\"$fov\"/>\n"
                   "<transform name=\"to_world\"><lookat origin=\"0,0,0\" target=\"0,0,1\" up=\"0,1,0\"/>"
                   "<rotate y=\"1\" angle=\"90\"/><translate value=\"1 2 3\"/></transform>\n"
                   "<film type=\"hdrfilm\"><integer name=\"width\" value=\"$w\"/>"
                   "<integer name=\"height\" value=\"$h\"/></film></sensor></scene>";
  assert_int_equal(mitsuba_text(v3, &cam, &err), GI_OK);
  cam_axes(&cam, f, u);
  assert_vec(cam.eye, 1, 2, 3, 1e-12);
  assert_vec(f, 1, 0, 0, 1e-12);
  assert_vec(u, 0, 1, 0, 1e-12);
  double want = deg(2 * atan(tan(rad(30)) * 1080.0 / 1920.0));
  printf("  fov 60 along x on 1920 x 1080: %.9f across the smaller side, want %.9f\n", cam.fov_deg, want);
  assert_true(fabs(cam.fov_deg - want) < 1e-9 && cam.width == 1920 && cam.height == 1080);
  gi_camera_fit(&cam, 256);
  assert_true(cam.width == 256 && cam.height == 144);
  /* A 35 mm focal length is along the film's diagonal (Mitsuba's rule). */
  const char *focal = "<scene version=\"3.0.0\"><sensor type=\"perspective\"><string name=\"focal_length\" "
                      "value=\"35mm\"/><film type=\"hdrfilm\"><integer name=\"width\" value=\"800\"/>"
                      "<integer name=\"height\" value=\"600\"/></film></sensor></scene>";
  assert_int_equal(mitsuba_text(focal, &cam, &err), GI_OK);
  double td = sqrt(36.0 * 36 + 24 * 24) / 70, ty = td / sqrt(1 + 9.0 / 16) * 0.75;
  printf("  35mm on 800 x 600: %.9f, want %.9f\n", cam.fov_deg, deg(2 * atan(ty)));
  assert_true(fabs(cam.fov_deg - deg(2 * atan(ty))) < 1e-9);
  /* No transform: at the origin looking along +z. */
  cam_axes(&cam, f, u);
  assert_vec(f, 0, 0, 1, 0);
}

/* Sensors that cannot be drawn as written fail naming the file's line and what is wrong. */
static void test_mitsuba_sensor_errors(void **state) {
  gi_camera cam;
  gi_error_info err;
  static const struct {
    const char *xml, *says;
  } bad[] = {
      {"<scene>\n<sensor type=\"perspective\"><transform name=\"to_world\"><scale x=\"-1\"/>"
       "<lookat origin=\"0,0,0\" target=\"0,0,1\" up=\"0,1,0\"/></transform></sensor></scene>", "mirrors"},
      {"<scene>\n\n<sensor type=\"perspective\"><float name=\"fov\" value=\"$fov\"/></sensor></scene>",
       "line 3: attribute 'value' uses $fov"},
      {"<scene><sensor type=\"thinlens\"/></scene>", "'thinlens'"},
      {"<scene><sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/><string name=\"focal_length\" "
       "value=\"50mm\"/></sensor></scene>", "both fov and focal_length"},
      {"<scene><sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/><string name=\"fov_axis\" "
       "value=\"z\"/></sensor></scene>", "fov_axis"},
      {"<scene><sensor type=\"perspective\"><transform name=\"to_world\"><skew value=\"1\"/></transform>"
       "</sensor></scene>", "<skew>"},
      {"<scene><sensor type=\"perspective\"><transform name=\"to_world\"><matrix value=\"1 0 0\"/></transform>"
       "</sensor></scene>", "16 numbers"},
      {"<scene><sensor type=\"perspective\"><film type=\"hdrfilm\"><integer name=\"width\" value=\"0\"/></film>"
       "</sensor></scene>", "film width"},
      {"<scene><sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/>", "not closed"},
      {"<scene><!-- <sensor type=\"perspective\"/> --></scene>", "no <sensor>"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    assert_int_equal(mitsuba_text(bad[i].xml, &cam, &err), GI_ERR_FORMAT);
    printf("  %s\n", err.msg);
    assert_non_null(strstr(err.msg, bad[i].says));
    assert_non_null(strstr(err.msg, "sensor.xml"));
  }
  assert_int_equal(gi_camera_from_mitsuba("/nonexistent/cam.xml", &cam, &err), GI_ERR_NOT_FOUND);
}

static void test_bad_cameras(void **state) {
  gi_error_info err = {0};
  gi_camera cam = {.eye = {0, 0, 0}, .target = {0, 0, 0}, .up = {0, 1, 0}, .fov_deg = 40, .width = 8, .height = 8};
  assert_int_equal(gi_camera_validate(&cam, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "same point"));
  cam.target[2] = 1, cam.fov_deg = 180;
  assert_int_equal(gi_camera_validate(&cam, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "fov"));
  cam.fov_deg = 40, cam.up[1] = 0, cam.up[2] = 1;
  assert_int_equal(gi_camera_validate(&cam, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "up"));
  cam.up[1] = 1, cam.up[2] = 0, cam.eye[0] = NAN;
  assert_int_equal(gi_camera_validate(&cam, &err), GI_ERR_NONFINITE);
  const char *bad = "<scene><sensor type=\"perspective\"><float name=\"fov\" value=\"x\"/></sensor></scene>";
  const char *xml = tu_write_file("cam.xml", bad, strlen(bad));
  assert_int_equal(gi_camera_from_mitsuba(xml, &cam, &err), GI_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "fov"));
}

/* Indirect light at anchors (every 4th pixel of every 4th row), mixed
 * between four that lie on the pixel's own surface: inside a lit room seen
 * into a corner (floor, two walls, a box on the floor, edges everywhere),
 * the anchors' pixels are the every-pixel view's bit for bit; a pixel with
 * an anchor of its cell on another surface (or off the image) is its own
 * gather, so bit for bit too (mixing across the edges moved such pixels by
 * up to 196% in a first version); the others are within 1% on average,
 * and at most half the diffuse cones are traced. */
#define ROOM_W 192
#define ROOM_H 144
static void room_hit_normal(const gi__cam *k, const gi_scene *s, int px, int py, float n[3]) {
  float w[3], t, ng[3];
  uint32_t tri;
  gi__cam_ray(k, (float)px + 0.5f, (float)py + 0.5f, w);
  n[0] = n[1] = n[2] = 0;
  if (!gi__intersect1(s, k->eye, w, 0, INFINITY, &t, &tri, ng)) return;
  float cw = gi__dot(ng, w);
  for (int a = 0; a < 3; a++) n[a] = cw > 0 ? -ng[a] : ng[a];
}

/* 1 when one of the four anchors (every 4th pixel) that pixel (x, y)
 * mixes with a weight above 0 lies on another surface (another normal) or
 * off the image: such a pixel gathers and samples its own light. */
static int off_surface(const float (*nrm)[3], int w, int h, int x, int y) {
  for (int j = y / 4 * 4; j <= y / 4 * 4 + 4; j += 4)
    for (int i = x / 4 * 4; i <= x / 4 * 4 + 4; i += 4) {
      if ((i == x / 4 * 4 + 4 && x % 4 == 0) || (j == y / 4 * 4 + 4 && y % 4 == 0)) continue; /* weight 0 */
      if (i >= w || j >= h || memcmp(nrm[j * w + i], nrm[y * w + x], sizeof nrm[0])) return 1;
    }
  return 0;
}

static void test_indirect_anchors(void **state) {
  gi_scene *s = tu_lit_room(0.7f);
  gi_error_info err = {0};
  gi_quality q = {.levels = 3, .res = 32, .voxel0 = 0.125};
  gi_cascade *c = NULL;
  double at[3] = {0, 1.2, 0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  gi_camera cam = {.eye = {1.5, 1.8, 1.5}, .target = {-2, 0.3, -2}, .up = {0, 1, 0}, .fov_deg = 70,
                   .width = ROOM_W, .height = ROOM_H};
  gi__cam k;
  assert_int_equal(gi__cam_setup(s, &cam, &k, &err), GI_OK);
  static float all[ROOM_W * ROOM_H * 3], mixed[ROOM_W * ROOM_H * 3], nrm[ROOM_W * ROOM_H][3];
  for (int y = 0; y < ROOM_H; y++)
    for (int x = 0; x < ROOM_W; x++) room_hit_normal(&k, s, x, y, nrm[y * ROOM_W + x]);
  gi_render_opts o1 = {.light_samples = 16, .threads = 2, .indirect_stride = 1};
  gi_render_opts o4 = {.light_samples = 16, .threads = 2}; /* the default: 4 */
  gi_render_stats s1, s4;
  assert_int_equal(gi_cascade_render_ex(c, &cam, &o1, all, &s1, &err), GI_OK);
  assert_int_equal(gi_cascade_render_ex(c, &cam, &o4, mixed, &s4, &err), GI_OK);
  double sum = 0, worst = 0;
  int n = 0, edge = 0;
  for (int y = 0; y < ROOM_H; y++)
    for (int x = 0; x < ROOM_W; x++) {
      const float *a = &all[3 * (y * ROOM_W + x)], *v = &mixed[3 * (y * ROOM_W + x)];
      assert_true(a[1] > 0);
      int own = x % 4 == 0 && y % 4 == 0;
      if (!own && off_surface(nrm, ROOM_W, ROOM_H, x, y)) own = 1, edge++;
      if (own) {
        assert_memory_equal(a, v, 3 * sizeof(float));
        continue;
      }
      double e = fabs(v[1] - a[1]) / a[1];
      sum += e, n++;
      worst = fmax(worst, e);
    }
  printf("room view: diffuse cones %llu every pixel, %llu at anchors; %d pixels by an edge or the border (their own gathers); the other %d, "
         "apart mean %.4f, max %.4f\n", (unsigned long long)s1.diffuse_cones, (unsigned long long)s4.diffuse_cones,
         edge, n, sum / n, worst);
  assert_true(edge > 0 && n > ROOM_W * ROOM_H / 2);
  assert_true(s4.diffuse_cones * 2 <= s1.diffuse_cones);
  assert_true(sum / n < 0.01);
  gi_render_opts bad = {.indirect_stride = GI_RENDER_MAX_STRIDE + 1};
  assert_int_equal(gi_cascade_render_ex(c, &cam, &bad, mixed, NULL, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "indirect_stride"));
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* The sampled lights (sky, emitters) at the same anchors: a ground under a
 * sky with a block on it and a lit panel facing down beside the block
 * (soft shadows, contact darkening). A pixel whose cell has an anchor on
 * another surface or off the image samples every light itself, so it is
 * the every-pixel view's bit for bit; against the every-pixel view at 16x
 * the light samples (the truth here), the mixed pixels are no worse than
 * the every-pixel view at the same samples: mixing four anchors' samples
 * may smooth a contact shadow, but not by more than it takes off the
 * noise. */
#define OPEN_W 96
#define OPEN_H 72
static void test_sampled_light_anchors(void **state) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.6f, 0.6f, 0.6f}, .roughness = 1};
  gi_material lamp = {.albedo = {0, 0, 0}, .emission = {6, 6, 6}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m), em = gi_mesh_builder_add_material(b, &lamp);
  const double g0[3] = {-6, 0, -6}, g1[3] = {-6, 0, 6}, g2[3] = {6, 0, 6}, g3[3] = {6, 0, -6};
  gi_mesh_builder_add_quad(b, g0, g1, g2, g3, mat);
  double blo[3] = {-1, 0, -1}, bhi[3] = {0.5, 1.2, 0.5};
  gi_mesh_builder_add_box(b, blo, bhi, mat);
  /* Facing down (-y), 1.5 m up beside the block. */
  const double p0[3] = {1, 1.5, -1}, p1[3] = {2, 1.5, -1}, p2[3] = {2, 1.5, 0}, p3[3] = {1, 1.5, 0};
  gi_mesh_builder_add_quad(b, p0, p1, p2, p3, em);
  gi_light sky = {.type = GI_LIGHT_SKY, .color = {0.5, 0.5, 0.5}};
  gi_scene *s = tu_build(b, "open", &sky, 1);
  gi_error_info err = {0};
  gi_quality q = {.levels = 3, .res = 32, .voxel0 = 0.125};
  gi_cascade *c = NULL;
  double at[3] = {0, 0.8, 0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  gi_camera cam = {.eye = {3, 3, 3}, .target = {-0.5, 0, -0.5}, .up = {0, 1, 0}, .fov_deg = 60,
                   .width = OPEN_W, .height = OPEN_H};
  gi__cam k;
  assert_int_equal(gi__cam_setup(s, &cam, &k, &err), GI_OK);
  static float truth[OPEN_W * OPEN_H * 3], all[OPEN_W * OPEN_H * 3], mixed[OPEN_W * OPEN_H * 3];
  static float nrm[OPEN_W * OPEN_H][3];
  for (int y = 0; y < OPEN_H; y++)
    for (int x = 0; x < OPEN_W; x++) room_hit_normal(&k, s, x, y, nrm[y * OPEN_W + x]);
  gi_render_opts ot = {.light_samples = 1024, .threads = 2, .indirect_stride = 1};
  gi_render_opts o1 = {.light_samples = 64, .threads = 2, .indirect_stride = 1};
  gi_render_opts o4 = {.light_samples = 64, .threads = 2};
  assert_int_equal(gi_cascade_render_ex(c, &cam, &ot, truth, NULL, &err), GI_OK);
  assert_int_equal(gi_cascade_render_ex(c, &cam, &o1, all, NULL, &err), GI_OK);
  assert_int_equal(gi_cascade_render_ex(c, &cam, &o4, mixed, NULL, &err), GI_OK);
  double e_all = 0, e_mix = 0, worst = 0;
  int n = 0, edge = 0;
  for (int y = 0; y < OPEN_H; y++)
    for (int x = 0; x < OPEN_W; x++) {
      size_t i = 3 * ((size_t)y * OPEN_W + x);
      if (nrm[y * OPEN_W + x][1] == 0 && nrm[y * OPEN_W + x][0] == 0 && nrm[y * OPEN_W + x][2] == 0) continue;
      if (off_surface(nrm, OPEN_W, OPEN_H, x, y)) {
        assert_memory_equal(&all[i], &mixed[i], 3 * sizeof(float));
        edge++;
        continue;
      }
      if (truth[i + 1] == 0) { /* the panel's back: black, as the mix must keep it */
        assert_true(mixed[i + 1] == 0);
        continue;
      }
      double ea = fabs(all[i + 1] - truth[i + 1]) / truth[i + 1], em_ = fabs(mixed[i + 1] - truth[i + 1]) / truth[i + 1];
      e_all += ea, e_mix += em_, n++;
      worst = fmax(worst, em_);
    }
  printf("open view: %d pixels sample every light themselves (edges, border); the other %d against 1024 samples "
         "per pixel: every pixel at 64 %.4f, anchors' mix %.4f (max %.4f)\n", edge, n, e_all / n, e_mix / n, worst);
  assert_true(edge > 0 && n > OPEN_W * OPEN_H / 2);
  assert_true(e_mix <= e_all);
  assert_true(e_mix / n < 0.02);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* A view reaching past what the cascade holds says how much of it: the
 * pixels whose surface lies outside every level (direct light alone) are
 * counted, as the plane's hits, found here by hand, say. None for a view
 * inside the cascade. */
static void test_pixels_outside(void **state) {
  (void)state;
  gi_scene *s = tu_sunlit_plane(0.5, 3.0, 100);
  gi_error_info err = {0};
  gi_quality q = {.levels = 2, .res = 16, .voxel0 = 1};
  gi_cascade *c = NULL;
  double at[3] = {0, 1, 0}, org[3];
  gi_scene_origin(s, org);
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  const gi_camera cams[2] = {{.eye = {0, 5, 0}, .target = {0, 0, 0}, .up = {0, 0, 1}, .fov_deg = 40, .width = 16,
                              .height = 12},
                             {.eye = {0, 40, 0}, .target = {0, 0, 0}, .up = {0, 0, 1}, .fov_deg = 90, .width = 32,
                              .height = 24}};
  for (int v = 0; v < 2; v++) {
    const gi_camera *cam = &cams[v];
    float *rgb = malloc((size_t)cam->width * cam->height * 3 * sizeof *rgb);
    assert_non_null(rgb);
    gi_render_stats st;
    assert_int_equal(gi_cascade_render_ex(c, cam, NULL, rgb, &st, &err), GI_OK);
    gi__cam k;
    assert_int_equal(gi__cam_setup(s, cam, &k, &err), GI_OK);
    uint64_t want = 0;
    for (int py = 0; py < cam->height; py++)
      for (int px = 0; px < cam->width; px++) {
        float w[3], x[3];
        gi__cam_ray(&k, (float)px + 0.5f, (float)py + 0.5f, w);
        float t = ((float)-org[1] - k.eye[1]) / w[1] * (1.f - GI_PRIMARY_PULL); /* the plane y = 0 */
        for (int a = 0; a < 3; a++) x[a] = k.eye[a] + t * w[a];
        want += gi__finest_level_at(c, x) < 0;
      }
    printf("view %d: %llu of %d pixels outside the cascade (%llu by hand)\n", v,
           (unsigned long long)st.pixels_outside, cam->width * cam->height, (unsigned long long)want);
    assert_true(v == 0 ? want == 0 : want > 100 && want < (uint64_t)(cam->width * cam->height));
    assert_true(st.pixels_outside + 2 >= want && st.pixels_outside <= want + 2);
    free(rgb);
  }
  gi_cascade_free(c);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_plane_under_sun),
      cmocka_unit_test(test_camera_on_floor),
      cmocka_unit_test(test_edge_pixels),
      cmocka_unit_test(test_mitsuba_camera),
      cmocka_unit_test(test_bad_cameras),
      cmocka_unit_test(test_mitsuba_sensor_forms),
      cmocka_unit_test(test_mitsuba_sensor_errors),
      cmocka_unit_test(test_indirect_anchors),
      cmocka_unit_test(test_sampled_light_anchors),
      cmocka_unit_test(test_pixels_outside),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
