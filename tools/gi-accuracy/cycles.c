/* cycles.c: Blender Cycles on the Munich aerial view, for the workloads
 * section (issue 11 quotes Cycles 3.4 on 2 threads at 16 samples).
 *
 * Blender runs headless with a script written next to the reference
 * cache: it imports the OBJ as it is (Z up, no axis change), gives every
 * material a plain diffuse BSDF of its Kd (our scene is Lambertian and
 * two-sided, as Blender's surfaces are), sets our sun (angle 0: a delta
 * light) and our sky as the world colour, the same pinhole camera, and
 * renders with Cycles on the CPU: 2 threads, no denoising, no adaptive
 * sampling, no clamping, a box pixel filter, deep bounces. The time is
 * the render call alone (scene sync, BVH build and path tracing), not
 * Blender's start-up or the OBJ import. The picture comes back as raw
 * floats and is compared with our reference like any other view. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "acc.h"
#include "gi/gi.h"

/* Cycles sample counts: issue 11's figure is at 16. */
static const int cycles_spp_full[] = {4, 16, 64, 256}, cycles_spp_quick[] = {16};
#define CYCLES_THREADS 2

static const char *const cycles_py =
    "import bpy, sys, time, array\n"
    "from mathutils import Vector\n"
    "a = sys.argv[sys.argv.index('--') + 1:]\n"
    "obj, out, spp, threads = a[0], a[1], int(a[2]), int(a[3])\n"
    "v = [float(x) for x in a[4:]]\n"
    "eye, tgt, fov, w, h = Vector(v[0:3]), Vector(v[3:6]), v[6], int(v[7]), int(v[8])\n"
    "sun_dir, sun_e, sky = Vector(v[9:12]), v[12:15], v[15:18]\n"
    "bpy.ops.wm.read_factory_settings(use_empty=True)\n"
    "sc = bpy.context.scene\n"
    "if hasattr(bpy.ops.wm, 'obj_import'):\n"
    "    bpy.ops.wm.obj_import(filepath=obj, forward_axis='Y', up_axis='Z')\n"
    "else:\n"
    "    bpy.ops.import_scene.obj(filepath=obj, axis_forward='Y', axis_up='Z')\n"
    "for m in bpy.data.materials:\n"
    "    m.use_nodes = True\n"
    "    nt = m.node_tree\n"
    "    col = (0.5, 0.5, 0.5, 1)\n"
    "    for n in nt.nodes:\n"
    "        if n.type == 'BSDF_PRINCIPLED':\n"
    "            col = tuple(n.inputs['Base Color'].default_value)\n"
    "    nt.nodes.clear()\n"
    "    d = nt.nodes.new('ShaderNodeBsdfDiffuse')\n"
    "    d.inputs['Color'].default_value = col\n"
    "    o = nt.nodes.new('ShaderNodeOutputMaterial')\n"
    "    nt.links.new(d.outputs[0], o.inputs[0])\n"
    "wd = bpy.data.worlds.new('sky')\n"
    "sc.world = wd\n"
    "wd.use_nodes = True\n"
    "bg = wd.node_tree.nodes['Background']\n"
    "bg.inputs[0].default_value = (sky[0], sky[1], sky[2], 1)\n"
    "bg.inputs[1].default_value = 1\n"
    "e = max(sun_e)\n"
    "if e > 0:\n"
    "    ld = bpy.data.lights.new('sun', 'SUN')\n"
    "    ld.energy = e\n"
    "    ld.color = (sun_e[0] / e, sun_e[1] / e, sun_e[2] / e)\n"
    "    ld.angle = 0\n"
    "    lo = bpy.data.objects.new('sun', ld)\n"
    "    lo.rotation_mode = 'QUATERNION'\n"
    "    lo.rotation_quaternion = sun_dir.to_track_quat('-Z', 'Y')\n"
    "    sc.collection.objects.link(lo)\n"
    "cd = bpy.data.cameras.new('cam')\n"
    "cd.angle = fov * 3.141592653589793 / 180\n"
    "cd.sensor_fit = 'HORIZONTAL' if w <= h else 'VERTICAL'\n"
    "co = bpy.data.objects.new('cam', cd)\n"
    "co.location = eye\n"
    "co.rotation_mode = 'QUATERNION'\n"
    "co.rotation_quaternion = (tgt - eye).to_track_quat('-Z', 'Y')\n"
    "sc.collection.objects.link(co)\n"
    "sc.camera = co\n"
    "r = sc.render\n"
    "r.engine = 'CYCLES'\n"
    "r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100\n"
    "r.threads_mode, r.threads = 'FIXED', threads\n"
    "r.image_settings.file_format, r.image_settings.color_depth = 'OPEN_EXR', '32'\n"
    "r.filepath = out + '.exr'\n"
    "sc.view_settings.view_transform = 'Standard'\n"
    "c = sc.cycles\n"
    "c.device, c.samples, c.seed = 'CPU', spp, 0\n"
    "c.use_adaptive_sampling = False\n"
    "c.use_denoising = False\n"
    "c.sample_clamp_direct = c.sample_clamp_indirect = 0\n"
    "c.blur_glossy = 0\n"
    "c.max_bounces = c.diffuse_bounces = c.glossy_bounces = 64\n"
    "c.pixel_filter_type, c.filter_width = 'BOX', 1.0\n"
    "t0 = time.time()\n"
    "bpy.ops.render.render(write_still=True)\n"
    "ms = (time.time() - t0) * 1000\n"
    "img = bpy.data.images.load(out + '.exr')\n"
    "array.array('f', img.pixels[:]).tofile(open(out + '.bin', 'wb'))\n"
    "print('GI_CYCLES_MS %.3f' % ms)\n";

int acc_have_blender(void) { return system("command -v blender > /dev/null 2>&1") == 0; }

/* The scene's sun (irradiance, travel direction) and sky radiance. */
static void scene_sun_sky(const gi_scene *s, float dir[3], float E[3], float sky[3]) {
  memset(E, 0, 3 * sizeof *E), memset(sky, 0, 3 * sizeof *sky);
  dir[0] = 0, dir[1] = 0, dir[2] = -1;
  for (size_t i = 0; i < gi_scene_num_lights(s); i++) {
    const gi_light *l = gi_scene_light(s, i);
    for (int k = 0; k < 3 && l->type == GI_LIGHT_SKY; k++) sky[k] += l->color[k];
    if (l->type == GI_LIGHT_SUN) memcpy(dir, l->direction, 3 * sizeof *dir), memcpy(E, l->color, 3 * sizeof *E);
  }
}

int acc_cycles_image(const char *obj, const char *work_dir, const gi_scene *s, const gi_camera *cam, int spp,
                     float *img, double *ms) {
  char script[1100], out[1100], cmd[4096], line[256];
  snprintf(script, sizeof script, "%s/cycles_view.py", work_dir);
  snprintf(out, sizeof out, "%s/cycles-%d", work_dir, spp);
  FILE *f = fopen(script, "w");
  if (!f || fputs(cycles_py, f) < 0 || fclose(f)) return fprintf(stderr, "gi-accuracy: cannot write %s\n", script), 0;
  float dir[3], E[3], sky[3];
  scene_sun_sky(s, dir, E, sky);
  snprintf(cmd, sizeof cmd,
           "blender -b --factory-startup --python '%s' -- '%s' '%s' %d %d %.9g %.9g %.9g %.9g %.9g %.9g %.9g %d %d "
           "%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g 2>&1",
           script, obj, out, spp, CYCLES_THREADS, cam->eye[0], cam->eye[1], cam->eye[2], cam->target[0],
           cam->target[1], cam->target[2], cam->fov_deg, cam->width, cam->height, dir[0], dir[1], dir[2], E[0], E[1],
           E[2], sky[0], sky[1], sky[2]);
  FILE *p = popen(cmd, "r");
  *ms = -1;
  while (p && fgets(line, sizeof line, p))
    if (!strncmp(line, "GI_CYCLES_MS ", 13)) *ms = atof(line + 13);
  int rc = p ? pclose(p) : -1;
  if (rc != 0 || !(*ms > 0)) return fprintf(stderr, "gi-accuracy: blender failed (exit %d): %s\n", rc, cmd), 0;
  size_t np = (size_t)cam->width * cam->height;
  float *rgba = malloc(np * 4 * sizeof *rgba);
  snprintf(out + strlen(out), sizeof out - strlen(out), ".bin");
  int ok = rgba && acc_cache_read(out, rgba, np * 4 * sizeof *rgba, NULL, 0);
  /* Blender's rows run from the bottom. */
  for (size_t i = 0; ok && i < np; i++) {
    size_t x = i % (size_t)cam->width, y = i / (size_t)cam->width, src = (cam->height - 1 - y) * cam->width + x;
    for (int k = 0; k < 3; k++) img[3 * i + k] = rgba[4 * src + k];
  }
  if (!ok) fprintf(stderr, "gi-accuracy: cannot read Blender's picture %s\n", out);
  free(rgba);
  return ok;
}

int acc_cycles_aerial(const acc_wl_opts *o, const gi_scene *s, const gi_camera *cam, acc_workload *w) {
  const int *spp = o->quick ? cycles_spp_quick : cycles_spp_full;
  int n = o->quick ? 1 : (int)(sizeof cycles_spp_full / sizeof cycles_spp_full[0]);
  float *img = malloc((size_t)cam->width * cam->height * 3 * sizeof *img);
  int ok = img != NULL;
  for (int i = 0; ok && i < n && w->num_cycles < ACC_WL_MAX_CYCLES; i++) {
    double ms;
    if (!(ok = acc_cycles_image(o->munich_obj, o->out_dir, s, cam, spp[i], img, &ms))) break;
    int k = w->num_cycles++;
    w->cycles_spp[k] = spp[i], w->cycles_ms[k] = ms;
    w->cycles_mre[k] = acc_view_image_error("munich-aerial", s, cam, w->ref_samples, o->out_dir, o->ref_version, img);
    fprintf(stderr, "  Blender Cycles %d samples: %.1f ms, MRE %.4f\n", spp[i], ms, w->cycles_mre[k]);
  }
  free(img);
  return ok;
}
