/* io/import_exact.h: OBJ and PLY geometry read in double precision.
 *
 * assimp parses positions into float, so a georeferenced file (UTM easting
 * ~7e5, northing ~5e6) loses up to 0.5 m before the scene can subtract its
 * origin. These readers keep every position as the file's double and hand
 * it to the mesh builder, which subtracts the scene origin in double; only
 * local coordinates become float. Materials and lights still come from
 * assimp (import_assimp.c), matched by the OBJ's usemtl names. */
#ifndef GI_IMPORT_EXACT_H
#define GI_IMPORT_EXACT_H

#include <stddef.h>
#include <stdint.h>
#include "gi/gi_error.h"

/* No usemtl before a face: assimp's default material. */
#define GI__EXACT_NO_MATERIAL UINT32_MAX

typedef struct gi__exact_mesh {
  double *v;       /* 3 per vertex, as written in the file */
  size_t nv, cap_v;
  uint32_t *tri;   /* 3 per triangle (convex polygons fanned, concave ones cut ear by ear) */
  uint32_t *mat;   /* per triangle: index into names, or GI__EXACT_NO_MATERIAL */
  size_t nt, cap_t, cap_m;
  char **names;    /* OBJ usemtl names in first-use order */
  size_t nnames, cap_names;
  uint32_t *name_slots; /* OBJ: open-addressing table of names (index + 1, 0 empty), cap_slots a power of 2 */
  size_t cap_slots;
  float *col;      /* 3 per vertex, linear, when any vertex has a colour (others white); else NULL */
  size_t cap_c;
  float *tcol;     /* PLY: 3 per triangle, its face's colour (linear; NAN: none), for triangles 0..ntc; or NULL */
  size_t ntc, cap_tc;
  float *uv;       /* OBJ: 2 per vt line (u, v up) */
  size_t nuv, cap_uv;
  size_t nvn;         /* OBJ vn statements seen: normals are not read, their indices are checked */
  uint32_t *tuv;   /* OBJ: 3 per triangle, each corner's vt (GI__EXACT_NO_UV: none) once any face has them; else NULL */
  size_t cap_tuv;
  char *mtllib;    /* OBJ: "mtllib NAME" per library it names, one per line, NUL-terminated; or NULL */
  size_t mtllib_len;
} gi__exact_mesh;

#define GI__EXACT_NO_UV UINT32_MAX

/* OBJ: v (with the common "v x y z r g b" colour extension), vt, f (v,
 * v/t, v//n, v/t/n, negative = relative), usemtl, mtllib (one line per
 * library for gi__exact_obj_stub: "mtllib a.mtl b.mtl" is two); other
 * statements are ignored. A bad number or vertex index fails with file and
 * line; a texture index out of range leaves that corner without
 * coordinates. */
gi_result gi__exact_read_obj(const char *path, gi__exact_mesh *m, gi_error_info *err);
/* PLY: ascii, binary_little_endian, binary_big_endian; x/y/z of any scalar
 * type (float and double included), colours when present (red green blue,
 * diffuse_red ..., or r g b) on vertices and on faces; faces from
 * vertex_indices/vertex_index; a file whose only surface is a 'tristrips'
 * element is refused, saying so. Colours in both formats are taken as
 * sRGB-encoded (8-bit values over 255, floats as they are) and stored
 * linear. */
gi_result gi__exact_read_ply(const char *path, gi__exact_mesh *m, gi_error_info *err);
void gi__exact_free(gi__exact_mesh *m);

/* The OBJ assimp reads in place of a read one, for its materials alone: m's
 * mtllib statements, then a triangle per material in first-use order (and
 * one before them when a face had no usemtl), so assimp makes the same
 * materials and meshes that use them without parsing the geometry again
 * (2M triangles: it doubled the load's time). NULL when out of memory;
 * the caller frees it (gi__free), *len its length. */
char *gi__exact_obj_stub(const gi__exact_mesh *m, size_t *len);
/* The same for a PLY, which carries no materials: one ASCII triangle. */
char *gi__exact_ply_stub(size_t *len);

/* An MTL file's text as assimp should read it. Its colour statements (Ka,
 * Kd, Ks, Ke, Tf) may give one number for all three channels (the MTL
 * format's rule), which assimp 5.2 reads as (r, 0, 0), and a blank after
 * the last number makes it fail the whole OBJ. Such statements come back
 * as "Kd r r r" and every colour line without trailing blanks. Returns
 * the new text (gi__free; *out_len its length), or NULL: with msg set
 * for a colour of two numbers or none (naming mtl_path and the line), with
 * msg "" when out of memory. */
char *gi__exact_mtl_normalise(const char *mtl_path, const char *text, size_t len, size_t *out_len, char *msg,
                              size_t msg_len);

#endif
