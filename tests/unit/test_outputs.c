/* test_outputs.c: the bake's files read back through OpenEXR and OpenVDB.
 *
 * A closed emissive box is baked and gathered; the probe EXR must hold
 * exactly the gathered numbers (FLOAT) or them within half precision
 * (HALF), with the header attributes; the VDB must hold every level's grids
 * with world transforms equal to the levels' boxes and values equal to the
 * cascade's own. No temporary file may remain. */
#include "test_util.h"
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"
#include "cascade/cascade_internal.h"
#include "light/light.h"
#include "trace/trace.h"
#include "scene/lights.h"
#include "answer/answer.h"

static gi_scene *box(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material wall = {.albedo = {0.7f, 0.5f, 0.3f}, .roughness = 1};
  gi_material lamp = {.albedo = {0.5f, 0.5f, 0.5f}, .emission = {5, 5, 5}, .roughness = 1};
  uint32_t mw = gi_mesh_builder_add_material(b, &wall), ml = gi_mesh_builder_add_material(b, &lamp);
  double lo[3] = {1000, 0, -20}, hi[3] = {1004, 3, -16};
  gi_mesh_builder_add_box(b, lo, hi, mw);
  /* A lamp facing down under the ceiling. */
  double a[3] = {1001.5, 2.9, -18.5}, bb[3] = {1002.5, 2.9, -18.5}, c[3] = {1002.5, 2.9, -17.5}, d[3] = {1001.5, 2.9, -17.5};
  gi_mesh_builder_add_quad(b, a, bb, c, d, ml);
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_scene_options opt = {.up = GI_UP_Y};
  assert_int_equal(gi_scene_build(b, "outbox", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

static int tmp_files_left(const char *dir) {
  DIR *d = opendir(dir);
  int n = 0;
  struct dirent *e;
  while (d && (e = readdir(d)))
    if (strstr(e->d_name, ".tmp.")) n++;
  if (d) closedir(d);
  return n;
}

static void test_probe_exr(void **state) {
  gi_scene *s = box();
  gi_quality q = {.levels = 3, .res = 16, .ao = 1};
  gi_cascade *c = NULL;
  gi_bake_report rep;
  gi_error_info err = {0};
  double at[3] = {1002, 1.5, -18};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, &rep, &err), GI_OK);
  double pts[9] = {1002, 1.5, -18, 1001, 0.5, -19, 1003.2, 2.0, -16.7};
  gi_probe pr[3];
  assert_int_equal(gi_cascade_gather(c, pts, 3, pr, NULL, &err), GI_OK);
  char path[512];
  snprintf(path, sizeof path, "%s/probes.exr", tu_tmpdir());
  for (int half = 0; half < 2; half++) {
    assert_int_equal(gi_probes_write_exr(path, pr, 3, s, at, &rep, half, &err), GI_OK);
    gi_exr_file *f = NULL;
    assert_int_equal(gi_exr_read(path, &f, &err), GI_OK);
    assert_int_equal(gi_exr_file_width(f), 3);
    assert_int_equal(gi_exr_file_height(f), 1);
    /* 3 x (R,G,B + irradiance + direct + indirect) + ao.Y + 27 SH. */
    assert_int_equal(gi_exr_file_num_channels(f), 12 + 1 + 27);
    static const char *const shn[9] = {"L00", "L1-1", "L10", "L11", "L2-2", "L2-1", "L20", "L21", "L22"};
    const char rgb[3] = {'R', 'G', 'B'};
    for (int k = 0; k < 3; k++) {
      char n1[8] = {rgb[k], 0}, n2[32], n3[32], n4[32];
      snprintf(n2, sizeof n2, "irradiance.%c", rgb[k]);
      snprintf(n3, sizeof n3, "direct.%c", rgb[k]);
      snprintf(n4, sizeof n4, "indirect.%c", rgb[k]);
      const float *R = gi_exr_file_channel(f, n1), *I = gi_exr_file_channel(f, n2),
                  *D = gi_exr_file_channel(f, n3), *N = gi_exr_file_channel(f, n4);
      assert_non_null(R); assert_non_null(I); assert_non_null(D); assert_non_null(N);
      for (int p = 0; p < 3; p++) {
        float tol = half ? 1e-3f * fabsf(pr[p].irradiance[k]) + 1e-6f : 0;
        assert_true(fabsf(R[p] - pr[p].irradiance[k]) <= tol);
        assert_true(fabsf(I[p] - pr[p].irradiance[k]) <= tol);
        assert_true(fabsf(D[p] - pr[p].direct[k]) <= (half ? 1e-3f * fabsf(pr[p].direct[k]) + 1e-6f : 0));
        assert_true(fabsf(N[p] - pr[p].indirect[k]) <= (half ? 1e-3f * fabsf(pr[p].indirect[k]) + 1e-6f : 0));
      }
      for (int i = 0; i < 9; i++) {
        char nm[32];
        snprintf(nm, sizeof nm, "sh.%s.%c", shn[i], rgb[k]);
        const float *S = gi_exr_file_channel(f, nm);
        assert_non_null(S);
        for (int p = 0; p < 3; p++)
          assert_true(fabsf(S[p] - pr[p].sh[i][k]) <= (half ? 1e-3f * fabsf(pr[p].sh[i][k]) + 1e-5f : 0));
      }
    }
    const float *ao = gi_exr_file_channel(f, "ao.Y");
    assert_non_null(ao);
    for (int p = 0; p < 3; p++) assert_true(ao[p] > 0 && ao[p] <= 1 && fabsf(ao[p] - pr[p].ao) < 1e-3f);
    assert_int_equal(gi_exr_file_channel_is_half(f, 0), half);
    assert_string_equal(gi_exr_file_attr(f, "gi.scene"), "outbox");
    assert_non_null(strstr(gi_exr_file_attr(f, "gi.viewpoint"), "1002"));
    assert_non_null(strstr(gi_exr_file_attr(f, "gi.effects"), "emissive=ran"));
    assert_non_null(strstr(gi_exr_file_attr(f, "gi.quality"), "levels=3 res=16"));
    /* The library wrote it, whichever program called it (it said "gi-server" from gi-bake too). */
    assert_true(strncmp(gi_exr_file_attr(f, "gi.version"), "libgi ", 6) == 0);
    gi_exr_file_free(f);
  }
  /* Irradiance is positive and finite everywhere inside the lit box. */
  for (int p = 0; p < 3; p++)
    for (int k = 0; k < 3; k++) assert_true(isfinite(pr[p].irradiance[k]) && pr[p].irradiance[k] > 0);
  /* A directory that does not exist: a clear I/O error, nothing written. */
  assert_int_equal(gi_probes_write_exr("/nonexistent-dir/p.exr", pr, 3, s, at, &rep, 0, &err), GI_ERR_IO);
  assert_int_equal(tmp_files_left(tu_tmpdir()), 0);
  gi_cascade_free(c);
  gi_scene_release(s);
}

static void test_cascade_vdb(void **state) {
  gi_scene *s = box();
  gi_quality q = {.levels = 3, .res = 16};
  gi_cascade *c = NULL;
  gi_bake_report rep;
  gi_error_info err = {0};
  double at[3] = {1002, 1.5, -18};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, &rep, &err), GI_OK);
  /* What the writer holds while it writes (dense copies of each level): the
   * server admits the encode by it. 3 levels of 16^3 voxels, 10 floats each
   * (28 with the face grids). */
  assert_true(gi_cascade_vdb_bytes_estimate(c, 0) == 3 * 4096 * 10 * sizeof(float));
  assert_true(gi_cascade_vdb_bytes_estimate(c, 1) == 3 * 4096 * 28 * sizeof(float));
  assert_true(gi_cascade_vdb_bytes_estimate(NULL, 1) == 0);
  char path[512];
  snprintf(path, sizeof path, "%s/cascade.vdb", tu_tmpdir());
  assert_int_equal(gi_cascade_write_vdb(c, path, 1, &err), GI_OK);
  gi_vdb_grid_info info[64];
  size_t n = 0;
  assert_int_equal(gi_vdb_read_info(path, info, 64, &n, &err), GI_OK);
  /* Per level: density, Cd, albedo, normal and 6 face grids; plus density and Cd. */
  assert_int_equal(n, 3 * 10 + 2);
  for (int d = 0; d < 3; d++) {
    char want[32];
    snprintf(want, sizeof want, "L%d_density", d);
    const gi_vdb_grid_info *g = NULL;
    for (size_t i = 0; i < n; i++)
      if (!strcmp(info[i].name, want)) g = &info[i];
    assert_non_null(g);
    assert_true(g->is_fog_volume);
    assert_true(fabs(g->voxel_size - rep.voxel_size[d]) < 1e-12);
    for (int a = 0; a < 3; a++)
      assert_true(fabs(g->index_to_world[a] - (rep.level_origin[d][a] + 0.5 * rep.voxel_size[d])) < 1e-9);
    /* Active voxels are exactly the voxels with any opacity. */
    const gi_level *L = &c->lv[d];
    long nonzero = 0;
    for (size_t i = 0; i < 16 * 16 * 16; i++)
      nonzero += (gi__vrad_alpha(&L->rad[i], 0) + gi__vrad_alpha(&L->rad[i], 1) + gi__vrad_alpha(&L->rad[i], 2)) > 0;
    assert_int_equal(g->active_voxels, nonzero);
    /* Values: a lattice of voxels (each read opens the file) against the cascade's own. */
    for (int k = 1; k < 16; k += 5)
      for (int j = 0; j < 16; j += 3)
        for (int i = 0; i < 16; i += 2) {
          uint32_t slot = gi__slot(L->cell0[0] + i, L->cell0[1] + j, L->cell0[2] + k, 16);
          gi_vrad_f rv, *r = &rv;
          gi__vrad_unpack(c, &L->rad[slot], r);
          float v[3];
          assert_int_equal(gi_vdb_read_value(path, want, i, j, k, v, &err), GI_OK);
          assert_true(fabsf(v[0] - (r->alpha[0] + r->alpha[1] + r->alpha[2]) / 3.f) < 1e-6f);
          if (i % 4 == 0) {
            char fn[32];
            snprintf(fn, sizeof fn, "L%d_face_py", d);
            assert_int_equal(gi_vdb_read_value(path, fn, i, j, k, v, &err), GI_OK);
            for (int ch = 0; ch < 3; ch++)
              assert_true(fabsf(v[ch] - r->p[GI_FACE_PY][ch]) <= 1e-6f * fmaxf(1.f, fabsf(r->p[GI_FACE_PY][ch])));
          }
        }
  }
  char buf[256];
  assert_int_equal(gi_vdb_read_meta(path, "L1_Cd", "gi.level", buf, sizeof buf, &err), GI_OK);
  assert_true(atof(buf) == 1.0);
  assert_int_equal(gi_vdb_read_meta(path, NULL, "gi.scene", buf, sizeof buf, &err), GI_OK);
  assert_string_equal(buf, "outbox");
  assert_int_equal(tmp_files_left(tu_tmpdir()), 0);
  gi_cascade_free(c);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_probe_exr),
      cmocka_unit_test(test_cascade_vdb),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
