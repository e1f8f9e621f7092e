/* march_simd.c: the cone march eight cones at a time (x86-64-v3 build only).
 *
 * A batch of cones (one or more gathers: apex, surface and direction per
 * cone, the step rule shared) runs through eight AVX2 lanes; a lane whose
 * cone stops takes the batch's next cone, so the lanes stay busy until
 * the batch runs out (cones of one hemisphere differ in length by 2-3x;
 * without the refill a third of the lane-steps idled). Each lane carries one cone
 * through the same steps as the scalar march (march_kernel.c, whose
 * comments say why each rule is what it is): the cone's width, its level
 * and blend, the level spans, the sample's trilinear cell, the empty-block
 * skip, the step and the compositing run in the eight lanes together; a
 * lane whose cone has stopped is masked off. Only the texel reads are per
 * lane: a sample's eight texels are summed 24 lanes at a time (F16C) and
 * reduced by that cone's faces. The eight cones' reads are independent,
 * so the CPU overlaps their cache misses, which one cone's march, a chain
 * of dependent steps, cannot. Results match the scalar march to float
 * rounding (test_texel). A recording batch also keeps each lane's lit
 * steps (trace.h: gi_tap), and gi__replay_tape_lanes replays them in
 * this march's own arithmetic, so a replay returns its bits. */
#include <immintrin.h>
#include "trace/march_internal.h"

#define LANES 8
/* Per-level constants as tables of 16, read per lane with two permutes. */
#define TAB 16
_Static_assert(GI_MAX_LEVELS <= TAB, "level tables hold every level");

typedef struct {
  const struct gi_cascade *c;
  gi_tap_rec *rec; /* NULL: no taps recorded */
  int n, R;
  float s[TAB], inv[TAB], lo[3][TAB];
  int32_t slot0[3][TAB];
  const char *rad[TAB];
  const uint8_t *busy[TAB], *busy4[TAB];
  /* Per lane: the face each axis reads (its first lane in read_lane's
   * register for that axis), the axis weights |w_a| (a face's projected
   * area: radiance, opacity and optical depth alike), and the same across
   * the surface's normal only (x (1 - n_a^2)). */
  int fb[LANES][3];
  uint8_t faces[LANES]; /* per lane: bit a set when w_a > 0 (gi_tap's face bits) */
  float k[LANES][3], kax[LANES][3];
  float span_in[GI_MAX_LEVELS][LANES], span_out[GI_MAX_LEVELS][LANES];
  /* Per lane: the cone's start (apex, direction, cosine to the surface
   * normal, apex height: < 0 in free space) and its march so far. */
  float o[3][LANES], w[3][LANES], iw[3][LANES], nw[LANES], h0[LANES];
  float t[LANES], a[LANES], occ[LANES], L[3][LANES], live[LANES];
  int32_t samples[LANES], steps[LANES], job[LANES];
} batch;

/* One sample per lane: what sample_level_ax returns. */
typedef struct {
  __m256 P[3], wal, sig, clear;
  int busy; /* lanes whose block held opacity (the others read zero) */
} sample8;

static inline __m256 tab16(const float *t, __m256i d) {
  __m256 a = _mm256_permutevar8x32_ps(_mm256_loadu_ps(t), d);
  __m256 b = _mm256_permutevar8x32_ps(_mm256_loadu_ps(t + 8), d);
  return _mm256_blendv_ps(a, b, _mm256_castsi256_ps(_mm256_cmpgt_epi32(d, _mm256_set1_epi32(7))));
}

static inline __m256i tab16i(const int32_t *t, __m256i d) {
  return _mm256_castps_si256(tab16((const float *)t, d));
}

#define V1(x) _mm256_set1_ps(x)
#define CMP(a, b, op) _mm256_cmp_ps(a, b, op)

/* gi__fast_exp_neg in eight lanes (the same polynomial). */
static inline __m256 exp_neg8(__m256 x) {
  __m256 y = _mm256_mul_ps(x, V1(-1.44269504f));
  __m256 k = _mm256_floor_ps(_mm256_add_ps(y, V1(0.5f)));
  __m256 f = _mm256_mul_ps(_mm256_sub_ps(y, k), V1(0.69314718f));
  __m256 p = _mm256_fmadd_ps(f, V1(0.0013888889f), V1(0.0083333338f));
  p = _mm256_fmadd_ps(f, p, V1(0.041666668f));
  p = _mm256_fmadd_ps(f, p, V1(0.16666667f));
  p = _mm256_fmadd_ps(f, p, V1(0.5f));
  p = _mm256_fmadd_ps(f, p, V1(1.f));
  p = _mm256_fmadd_ps(f, p, V1(1.f));
  __m256i e = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvttps_epi32(k), _mm256_set1_epi32(127)), 23);
  __m256 r = _mm256_mul_ps(p, _mm256_castsi256_ps(e));
  return _mm256_and_ps(r, CMP(x, V1(87.f), _CMP_LT_OQ)); /* 0 beyond, and for NaN */
}

/* The trilinear cell of p on each lane's level d: the eight corner
 * texels' byte offsets into the level and their weights (corner i = dx + 2 dy
 * + 4 dz), and how far along w the sample stays in its 2x2x2 block (run;
 * 0 where the cell was clamped to the window). Corner 0's slot is also
 * the block's, which the busy mask is indexed by. */
typedef struct {
  float wt[8][LANES], run[LANES], run4[LANES];
  uint32_t corner[8][LANES]; /* bytes: R^3 x 48 < 2^32 for R <= 256 */
  uint32_t block[LANES];      /* corner 0's slot */
  uint32_t block4[LANES];     /* its busy4 block */
} cell8;

/* What corners needs from locate, kept apart from cell8 (whose address
 * read_lane takes) so that it can stay in registers. */
typedef struct {
  __m256 f[3];       /* the fraction along each axis */
  __m256i off[3][2]; /* each axis's two slots times its stride */
} frac8;

static inline __attribute__((always_inline)) void locate(const batch *b, __m256i d, const __m256 p[3],
                                                          const __m256 w[3], const __m256 iw[3], cell8 *out,
                                                          frac8 *fo) {
  __m256 inv = tab16(b->inv, d), sd = tab16(b->s, d), run = V1(INFINITY), run4 = V1(INFINITY);
  __m256i R = _mm256_set1_epi32(b->R), Rm2 = _mm256_set1_epi32(b->R - 2), one = _mm256_set1_epi32(1);
  __m256i blk4 = _mm256_setzero_si256(), nb = _mm256_set1_epi32(gi__busy4_side(b->R));
  __m256 f[3];
  __m256i off[3][2];
  for (int a = 0; a < 3; a++) {
    __m256 u = _mm256_sub_ps(_mm256_mul_ps(_mm256_sub_ps(p[a], tab16(b->lo[a], d)), inv), V1(0.5f));
    __m256 fl = _mm256_floor_ps(u);
    __m256i i0 = _mm256_cvttps_epi32(fl);
    __m256 low = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_setzero_si256(), i0));
    __m256 high = _mm256_castsi256_ps(_mm256_cmpgt_epi32(i0, Rm2));
    i0 = _mm256_min_epi32(_mm256_max_epi32(i0, _mm256_setzero_si256()), Rm2);
    fl = _mm256_blendv_ps(fl, _mm256_setzero_ps(), low);
    u = _mm256_blendv_ps(u, _mm256_max_ps(u, _mm256_setzero_ps()), low);
    fl = _mm256_blendv_ps(fl, V1((float)(b->R - 2)), high);
    u = _mm256_blendv_ps(u, _mm256_min_ps(u, V1((float)(b->R - 1))), high);
    run = _mm256_andnot_ps(_mm256_or_ps(low, high), run);
    run4 = _mm256_andnot_ps(_mm256_or_ps(low, high), run4);
    f[a] = _mm256_sub_ps(u, fl);
    /* Inside the block while u stays in [fl, fl + 1]; inside the busy4
     * block `more` whole cells further (march_kernel.c). */
    __m256 pos = CMP(w[a], _mm256_setzero_ps(), _CMP_GT_OQ), nz = CMP(w[a], _mm256_setzero_ps(), _CMP_NEQ_OQ);
    __m256 gap = _mm256_blendv_ps(f[a], _mm256_sub_ps(V1(1.f), f[a]), pos);
    __m256 along = _mm256_mul_ps(sd, iw[a]); /* one cell's length along w (march_kernel.c) */
    __m256 r = _mm256_mul_ps(gap, along);
    run = _mm256_blendv_ps(run, _mm256_min_ps(r, run), nz);
    __m256i in4 = _mm256_and_si256(i0, _mm256_set1_epi32(GI_EMPTY_BLOCK - 1));
    __m256 more = _mm256_blendv_ps(_mm256_cvtepi32_ps(in4),
                                   _mm256_cvtepi32_ps(_mm256_sub_epi32(_mm256_set1_epi32(GI_EMPTY_BLOCK - 1), in4)), pos);
    __m256 r4 = _mm256_mul_ps(_mm256_add_ps(more, gap), along);
    run4 = _mm256_blendv_ps(run4, _mm256_min_ps(r4, run4), nz);
    __m256i bi = _mm256_srli_epi32(i0, 2); /* i0 / GI_EMPTY_BLOCK */
    blk4 = a == 0 ? bi : _mm256_add_epi32(blk4, _mm256_mullo_epi32(bi, a == 1 ? nb : _mm256_mullo_epi32(nb, nb)));
    __m256i s0 = _mm256_add_epi32(tab16i(b->slot0[a], d), i0);
    s0 = _mm256_sub_epi32(s0, _mm256_andnot_si256(_mm256_cmpgt_epi32(R, s0), R)); /* s0 >= R: wrap */
    __m256i s1 = _mm256_add_epi32(s0, one);
    s1 = _mm256_andnot_si256(_mm256_cmpeq_epi32(s1, R), s1);
    __m256i stride = _mm256_set1_epi32(a == 0 ? 1 : (a == 1 ? b->R : b->R * b->R));
    off[a][0] = _mm256_mullo_epi32(s0, stride);
    off[a][1] = _mm256_mullo_epi32(s1, stride);
  }
  _mm256_storeu_ps(out->run, run);
  _mm256_storeu_ps(out->run4, run4);
  _mm256_storeu_si256((__m256i *)out->block4, blk4);
  _mm256_storeu_si256((__m256i *)out->block, _mm256_add_epi32(_mm256_add_epi32(off[2][0], off[1][0]), off[0][0]));
  for (int a = 0; a < 3; a++) fo->f[a] = f[a], fo->off[a][0] = off[a][0], fo->off[a][1] = off[a][1];
}

/* The eight corners' weights and byte offsets of the cell locate found:
 * only a step where some lane reads texels needs them (most read none). */
static inline __attribute__((always_inline)) void corners(const frac8 *fo, cell8 *cl) {
  __m256 g[3][2];
  for (int a = 0; a < 3; a++) g[a][0] = _mm256_sub_ps(V1(1.f), fo->f[a]), g[a][1] = fo->f[a];
  __m256i texel = _mm256_set1_epi32((int)sizeof(gi_vrad));
  for (int i = 0; i < 8; i++) {
    int dx = i & 1, dy = (i >> 1) & 1, dz = i >> 2;
    /* The scalar march's order: (x y) z. */
    _mm256_storeu_ps(cl->wt[i], _mm256_mul_ps(_mm256_mul_ps(g[0][dx], g[1][dy]), g[2][dz]));
    __m256i o = _mm256_add_epi32(_mm256_add_epi32(fo->off[2][dz], fo->off[1][dy]), fo->off[0][dx]);
    _mm256_storeu_si256((__m256i *)cl->corner[i], _mm256_mullo_epi32(o, texel));
  }
}

/* What one lane's sample leaves in its row: P (3 channels), opacity
 * weight, optical depth; transposed into sample8 after. */
enum { ROW_P = 0, ROW_WAL = 3, ROW_TAU = 4 };

/* Where axis a's face (its w_a > 0 one when pos) starts in that axis's
 * register of texel_faces (src[a] there). */
static inline int face_lane(int a, int pos) { return 3 * (2 * a + pos) - (a == 0 ? 0 : a == 1 ? 4 : 12); }

/* The trilinear sum of a sample's eight texels (corner i at byte
 * corner[i * stride] of rad, weight wt[i * stride]), all 24 lanes, and
 * each axis's face (starting at fb[a], face_lane) from the one register
 * holding all of it (x: texel lanes 0-7, faces 0 and 1; y: lanes 4-11,
 * faces 2 and 3; z: lanes 12-19, faces 4 and 5) into T[a]'s lanes 0-2.
 * a2 keeps lanes 16-23 (opacity, depth). The march (read_lane) and its
 * replay (tap_sample8) both take this, so their sums are one arithmetic. */
static inline __attribute__((always_inline)) void texel_faces(const char *rad, const uint32_t *corner,
                                                             const float *wt, int stride, const int fb[3],
                                                             __m256 T[3], __m256 *a2out) {
  __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps(), a2 = _mm256_setzero_ps();
  for (int i = 0; i < 8; i++) {
    __m256 wi = _mm256_broadcast_ss(&wt[i * stride]);
    const __m128i *h = (const __m128i *)(rad + corner[i * stride]);
    a0 = _mm256_fmadd_ps(wi, _mm256_cvtph_ps(_mm_loadu_si128(h)), a0);
    a1 = _mm256_fmadd_ps(wi, _mm256_cvtph_ps(_mm_loadu_si128(h + 1)), a1);
    a2 = _mm256_fmadd_ps(wi, _mm256_cvtph_ps(_mm_loadu_si128(h + 2)), a2);
  }
  __m256 src[3] = {a0, _mm256_permute2f128_ps(a0, a1, 0x21), _mm256_permute2f128_ps(a1, a2, 0x21)};
  const __m256i iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  for (int a = 0; a < 3; a++) T[a] = _mm256_permutevar8x32_ps(src[a], _mm256_add_epi32(_mm256_set1_epi32(fb[a]), iota));
  *a2out = a2;
}

/* A sample's radiance from its faces T weighted k: the scalar kernel's
 * order, with fused steps. */
static inline __m256 faces_radiance(const float k[3], const __m256 T[3]) {
  return _mm256_fmadd_ps(_mm256_broadcast_ss(&k[2]), T[2],
                         _mm256_fmadd_ps(_mm256_broadcast_ss(&k[1]), T[1], _mm256_mul_ps(_mm256_broadcast_ss(&k[0]), T[0])));
}

/* One busy lane's texel reads: sample_level_ax's second half, as one row
 * (lanes 5-7 unused). The sum stays in registers: storing it and reading
 * each face back with a load that straddled two of the stores (faces 2
 * and 5) stalled store forwarding, a sixth of this function's time. */
static __m256 read_lane(const batch *b, int l, int d, const cell8 *cl, int ax) {
  /* The weights and corners read from the lane's column. */
  __m256 T[3], a2;
  texel_faces(b->rad[d], &cl->corner[0][l], &cl->wt[0][l], LANES, b->fb[l], T, &a2);
  /* Its opacity (texel lane 18 + a) and depth (21 + a) into lanes 3, 4. */
  for (int a = 0; a < 3; a++)
    T[a] = _mm256_blend_ps(T[a], _mm256_permutevar8x32_ps(a2, _mm256_setr_epi32(0, 0, 0, 2 + a, 5 + a, 0, 0, 0)), 0x18);
  /* P with fused steps, the opacity and depth without (the scalar kernel's order). */
  const float *k = ax ? b->kax[l] : b->k[l];
  __m256 k0 = _mm256_broadcast_ss(&k[0]), k1 = _mm256_broadcast_ss(&k[1]), k2 = _mm256_broadcast_ss(&k[2]);
  __m256 P = faces_radiance(k, T);
  __m256 W = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(k0, T[0]), _mm256_mul_ps(k1, T[1])), _mm256_mul_ps(k2, T[2]));
  return _mm256_blend_ps(P, W, 0x18);
}

/* rows[l][j] -> col[j] lane l: the 8x8 transpose. */
static inline void transpose8(const float rows[LANES][LANES], __m256 col[LANES]) {
  __m256 r[8], t[8];
  for (int i = 0; i < 8; i++) r[i] = _mm256_loadu_ps(rows[i]);
  for (int i = 0; i < 8; i += 2) {
    t[i] = _mm256_unpacklo_ps(r[i], r[i + 1]);
    t[i + 1] = _mm256_unpackhi_ps(r[i], r[i + 1]);
  }
  for (int i = 0; i < 8; i += 4) {
    r[i] = _mm256_shuffle_ps(t[i], t[i + 2], 0x44);
    r[i + 1] = _mm256_shuffle_ps(t[i], t[i + 2], 0xEE);
    r[i + 2] = _mm256_shuffle_ps(t[i + 1], t[i + 3], 0x44);
    r[i + 3] = _mm256_shuffle_ps(t[i + 1], t[i + 3], 0xEE);
  }
  for (int i = 0; i < 4; i++) {
    col[i] = _mm256_permute2f128_ps(r[i], r[i + 4], 0x20);
    col[i + 4] = _mm256_permute2f128_ps(r[i], r[i + 4], 0x31);
  }
}

/* Samples level d (per lane) at p for the lanes in `act`; lanes in `ax`
 * read the axes across the surface's normal only; lanes in `far` may
 * cross an empty busy4 block (march_kernel.c). The busy masks are read
 * for every lane first and only the busy lanes read texels: a branch per
 * lane on busy (60-75% of samples are empty) mispredicted often and each
 * miss threw away the texel loads already in flight. */
static void sample8_at(const batch *b, __m256i d, __m256 act, __m256 ax, __m256 far, const __m256 p[3],
                       const __m256 w[3], const __m256 iw[3], sample8 *out) {
  cell8 cl;
  frac8 fr;
  locate(b, d, p, w, iw, &cl, &fr);
  int32_t dl[LANES];
  _mm256_storeu_si256((__m256i *)dl, d);
  int m = _mm256_movemask_ps(act), mx = _mm256_movemask_ps(ax), busy = 0, open4 = 0;
  for (int l = 0; l < LANES; l++) {
    int dd = dl[l] & (TAB - 1); /* idle lanes may hold n: any table entry is readable */
    busy |= (b->busy[dd][cl.block[l]] != 0) << l;
  }
  busy &= m;
  /* Only an empty far lane asks its busy4 block (most steps have none). */
  for (int todo = _mm256_movemask_ps(far) & m & ~busy; todo; todo &= todo - 1) {
    int l = __builtin_ctz((unsigned)todo);
    open4 |= (b->busy4[dl[l]][cl.block4[l]] == 0) << l;
  }
  if (busy) {
    /* Whole rows, each one store, so the transpose's loads forward. The
     * idle lanes' zeros by mask: a loop over all eight, or a memset, became
     * rep stos, 7% of this function. */
    float rows[LANES][LANES];
    corners(&fr, &cl);
    for (int todo = ~busy & 0xff; todo; todo &= todo - 1)
      _mm256_storeu_ps(rows[__builtin_ctz((unsigned)todo)], _mm256_setzero_ps());
    for (int todo = busy; todo; todo &= todo - 1) {
      int l = __builtin_ctz((unsigned)todo);
      _mm256_storeu_ps(rows[l], read_lane(b, l, dl[l], &cl, (mx >> l) & 1));
    }
    __m256 col[LANES];
    transpose8((const float(*)[LANES])rows, col);
    __m256 scale = V1(b->c->rad_scale);
    for (int ch = 0; ch < 3; ch++) out->P[ch] = _mm256_mul_ps(col[ROW_P + ch], scale);
    out->wal = col[ROW_WAL];
    out->sig = _mm256_mul_ps(col[ROW_TAU], tab16(b->inv, d));
  } else {
    /* No lane read a texel: the zeros the sums above would give, bit for bit (+0 times a scale). */
    for (int ch = 0; ch < 3; ch++) out->P[ch] = _mm256_setzero_ps();
    out->wal = out->sig = _mm256_setzero_ps();
  }
  /* Empty lanes may skip: to the busy4 block's end where far and that block is empty too. */
  __m256i bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  __m256 lane_open4 = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(open4), bit), bit));
  __m256 lane_empty =
      _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(~busy & m), bit), bit));
  __m256 clear = _mm256_blendv_ps(_mm256_loadu_ps(cl.run), _mm256_loadu_ps(cl.run4), _mm256_and_ps(far, lane_open4));
  out->clear = _mm256_and_ps(clear, lane_empty);
  out->busy = busy;
}

/* The step rule all cones share, and the cascade's finest voxel. */
typedef struct {
  float tan_half, step, ao_lambda, s0, inv_s0, inv_ks0;
} par8;

/* The lanes' march in registers; batch holds the same in columns while
 * lanes are refilled. */
typedef struct {
  __m256 t, a, occ, L[3], act;
  __m256i samples, steps;
  __m256 o[3], w[3], iw[3], nw, h0;
} state8;

/* The level each lane samples, as the scalar march picks it: the cone's
 * width (or the surface rule's height) gives d0 and the blend; the first
 * level from d0 on whose span holds t is read. *next: lanes whose level
 * d+1 also holds t. Returns n where no level does. */
static __m256i pick_level(const batch *b, const par8 *q, const state8 *st, __m256 D, __m256 *near, __m256 *frac,
                          __m256 *next, __m256i *d0out) {
  __m256 x = _mm256_mul_ps(D, V1(q->inv_s0));
  __m256 surf = CMP(st->h0, _mm256_setzero_ps(), _CMP_GE_OQ);
  __m256 h = _mm256_add_ps(st->h0, _mm256_mul_ps(st->t, st->nw)); /* no FMA: see step8 */
  __m256 xh = _mm256_mul_ps(_mm256_max_ps(h, V1(GI_MIN_HEIGHT)), V1(q->inv_ks0));
  *near = _mm256_and_ps(surf, CMP(xh, x, _CMP_LT_OQ));
  x = _mm256_blendv_ps(x, _mm256_max_ps(_mm256_min_ps(x, xh), V1(1.f)), surf);
  /* Level from the exponent, blend from the mantissa (see march_kernel.c). */
  __m256i xb = _mm256_castps_si256(x);
  __m256i d0 = _mm256_sub_epi32(_mm256_srli_epi32(xb, 23), _mm256_set1_epi32(127));
  __m256 mant = _mm256_castsi256_ps(
      _mm256_or_si256(_mm256_and_si256(xb, _mm256_set1_epi32(0x007fffff)), _mm256_set1_epi32(0x3f800000)));
  __m256 fr = _mm256_andnot_ps(*near, _mm256_sub_ps(mant, V1(1.f)));
  __m256 coarsest = _mm256_castsi256_ps(_mm256_cmpgt_epi32(d0, _mm256_set1_epi32(b->n - 2)));
  d0 = _mm256_min_epi32(d0, _mm256_set1_epi32(b->n - 1));
  fr = _mm256_andnot_ps(coarsest, fr);
  *near = _mm256_andnot_ps(coarsest, *near); /* the full step on the coarsest level */
  __m256i d = _mm256_set1_epi32(b->n);
  __m256 has_next = _mm256_setzero_ps(), prev = _mm256_setzero_ps();
  /* No lane takes a level below its d0: the loop stops at the lanes' least. */
  __m128i m4 = _mm_min_epi32(_mm256_castsi256_si128(d0), _mm256_extracti128_si256(d0, 1));
  m4 = _mm_min_epi32(m4, _mm_shuffle_epi32(m4, 0x4e));
  int kmin = _mm_cvtsi128_si32(_mm_min_epi32(m4, _mm_shuffle_epi32(m4, 0xb1)));
  for (int k = b->n - 1; k >= kmin && k >= 0; k--) {
    __m256 ok = _mm256_and_ps(CMP(_mm256_loadu_ps(b->span_in[k]), st->t, _CMP_LE_OQ),
                              CMP(st->t, _mm256_loadu_ps(b->span_out[k]), _CMP_LE_OQ));
    __m256 sel = _mm256_and_ps(ok, _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(k + 1), d0)));
    d = _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(d), _mm256_castsi256_ps(_mm256_set1_epi32(k)), sel));
    has_next = _mm256_blendv_ps(has_next, prev, sel);
    prev = ok;
  }
  /* Pushed to a coarser level by position, not by size: no blend. */
  *frac = _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(d, d0)), fr);
  *next = has_next;
  *d0out = d0;
  return d;
}

/* Folds one sample into the lanes in act: the step, the empty-block
 * skip, the opacity and front-to-back compositing (any: some lane's
 * sample read a texel; else only the step). */
static void composite(const par8 *q, state8 *st, __m256 act, __m256 near, __m256 sd, __m256 D, const sample8 *s,
                      __m256 clear2, int any, __m256 *lit_out, __m256 *k_out) {
  __m256 dt = _mm256_mul_ps(_mm256_blendv_ps(V1(q->step), V1(gi__minf(q->step, GI_NEAR_SURFACE_STEP)), near), sd);
  __m256 run = _mm256_min_ps(s->clear, clear2);
  dt = _mm256_blendv_ps(dt, _mm256_mul_ps(dt, _mm256_ceil_ps(_mm256_div_ps(run, dt))), CMP(run, dt, _CMP_GT_OQ));
  if (!any) {
    /* Nothing read: opacity 0, so L, a and occ stay as they are, bit for bit. */
    *lit_out = *k_out = _mm256_setzero_ps();
    st->t = _mm256_blendv_ps(st->t, _mm256_add_ps(st->t, dt), act);
    st->act = _mm256_and_ps(act, CMP(st->a, V1(GI_OPAQUE_ALPHA), _CMP_LT_OQ));
    return;
  }
  __m256 as = _mm256_sub_ps(V1(1.f), exp_neg8(_mm256_mul_ps(s->sig, dt)));
  __m256 a = st->a, ta = _mm256_sub_ps(V1(1.f), a);
  __m256 lit = _mm256_and_ps(act, _mm256_and_ps(CMP(as, _mm256_setzero_ps(), _CMP_GT_OQ),
                                                CMP(s->wal, V1(GI_MIN_SAMPLE_WEIGHT), _CMP_GT_OQ)));
  __m256 k = _mm256_div_ps(_mm256_mul_ps(ta, as), s->wal);
  for (int ch = 0; ch < 3; ch++) st->L[ch] = _mm256_blendv_ps(st->L[ch], _mm256_fmadd_ps(k, s->P[ch], st->L[ch]), lit);
  *lit_out = lit, *k_out = k;
  __m256 occ = st->occ;
  __m256 att = _mm256_fmadd_ps(V1(q->ao_lambda * 0.5f), D, V1(1.f));
  occ = _mm256_add_ps(occ, _mm256_div_ps(_mm256_mul_ps(_mm256_sub_ps(V1(1.f), occ), as), att));
  st->occ = _mm256_blendv_ps(st->occ, occ, act);
  a = _mm256_add_ps(a, _mm256_mul_ps(ta, as));
  st->a = _mm256_blendv_ps(st->a, a, act);
  st->t = _mm256_blendv_ps(st->t, _mm256_add_ps(st->t, dt), act);
  st->act = _mm256_and_ps(act, CMP(st->a, V1(GI_OPAQUE_ALPHA), _CMP_LT_OQ));
}

/* The taps of the lanes in lit (see gi_tap): the step at p on level d
 * with each lane's compositing weight k, and where `two` blends in level
 * d + 1 by frac, that too; busy1 and busy2: the lanes whose samples read
 * opacity. */
static void record8(const batch *b, __m256 lit, __m256 k, const __m256 p[3], __m256i d, __m256 ax, __m256 two,
                    __m256 frac, int busy1, int busy2) {
  float P[3][LANES], K[LANES], F[LANES];
  int32_t D[LANES];
  for (int a = 0; a < 3; a++) _mm256_storeu_ps(P[a], p[a]);
  _mm256_storeu_ps(K, k);
  _mm256_storeu_ps(F, frac);
  _mm256_storeu_si256((__m256i *)D, d);
  int mx = _mm256_movemask_ps(ax), m2 = _mm256_movemask_ps(two), lit_m = _mm256_movemask_ps(lit);
  gi_tap_rec *r = b->rec;
  /* Room for every lane's tap at once, then each written in place (full: not replayed). */
  if (!gi__tap_reserve(r, (size_t)__builtin_popcount((unsigned)lit_m))) return;
  for (int todo = lit_m; todo; todo &= todo - 1) {
    int l = __builtin_ctz((unsigned)todo), blend = m2 >> l & 1;
    /* Never both: a step pushed to a coarser level (ax) does not blend. */
    const float *kw = (mx >> l & 1) ? b->kax[l] : b->k[l];
    gi_tap *t = &r->t[r->n++];
    t->job = (uint16_t)b->job[l];
    t->d = (uint8_t)D[l];
    t->flags = (uint8_t)(b->faces[l] | (busy1 >> l & 1 ? GI_TAP_BUSY : 0) |
                         (blend && (busy2 >> l & 1) ? GI_TAP_BUSY2 : 0) | (blend ? GI_TAP_BLEND : 0) |
                         (mx >> l & 1 ? GI_TAP_KALT : 0));
    for (int a = 0; a < 3; a++) t->p[a] = P[a][l], t->k[a] = kw[a];
    t->kk = K[l], t->frac = blend ? F[l] : 0, t->alpha = 0;
  }
}

/* One step of every live lane. */
static void step8(const batch *b, const par8 *q, state8 *st) {
  __m256 D = _mm256_max_ps(_mm256_mul_ps(_mm256_mul_ps(V1(2.f), st->t), V1(q->tan_half)), V1(q->s0));
  __m256 near, frac, next;
  __m256i d0;
  __m256i d = pick_level(b, q, st, D, &near, &frac, &next, &d0);
  __m256 act = _mm256_and_ps(st->act, _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(b->n), d)));
  st->act = act;
  if (!_mm256_movemask_ps(act)) return;
  st->steps = _mm256_sub_epi32(st->steps, _mm256_castps_si256(act));
  __m256 p[3];
  /* Positions, heights, steps and opacity round as in the scalar march
   * (no FMA): they decide levels, blocks and the cone's end, and a fused
   * rounding there sends a cone down another path now and then. */
  for (int a = 0; a < 3; a++) p[a] = _mm256_add_ps(st->o[a], _mm256_mul_ps(st->t, st->w[a]));
  __m256 sd = tab16(b->s, d);
  /* Pushed to a coarser level near the surface it started from: read
   * the axes across the normal only (see march_kernel.c). */
  __m256 h = _mm256_add_ps(st->h0, _mm256_mul_ps(st->t, st->nw));
  __m256 ax = _mm256_and_ps(_mm256_and_ps(CMP(st->h0, _mm256_setzero_ps(), _CMP_GE_OQ),
                                          _mm256_castsi256_ps(_mm256_cmpgt_epi32(d, d0))),
                            CMP(h, _mm256_mul_ps(V1(GI_TRILINEAR_REACH), sd), _CMP_LT_OQ));
  __m256 far = _mm256_and_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(d0, _mm256_set1_epi32(b->n - 1))),
                             _mm256_or_ps(CMP(st->h0, _mm256_setzero_ps(), _CMP_LT_OQ),
                                          CMP(st->nw, _mm256_setzero_ps(), _CMP_GE_OQ)));
  sample8 s;
  sample8_at(b, d, act, ax, far, p, st->w, st->iw, &s);
  st->samples = _mm256_sub_epi32(st->samples, _mm256_castps_si256(act));
  __m256 two = _mm256_and_ps(act, _mm256_and_ps(next, CMP(frac, _mm256_setzero_ps(), _CMP_GT_OQ)));
  __m256 clear2 = V1(INFINITY);
  int busy2 = 0;
  if (_mm256_movemask_ps(two)) {
    sample8 s2;
    sample8_at(b, _mm256_add_epi32(d, _mm256_set1_epi32(1)), two, _mm256_setzero_ps(), _mm256_setzero_ps(), p, st->w,
               st->iw, &s2);
    st->samples = _mm256_sub_epi32(st->samples, _mm256_castps_si256(two));
    for (int ch = 0; ch < 3; ch++)
      s.P[ch] = _mm256_blendv_ps(s.P[ch], _mm256_fmadd_ps(frac, _mm256_sub_ps(s2.P[ch], s.P[ch]), s.P[ch]), two);
    s.wal = _mm256_blendv_ps(s.wal, _mm256_fmadd_ps(frac, _mm256_sub_ps(s2.wal, s.wal), s.wal), two);
    s.sig = _mm256_blendv_ps(s.sig, _mm256_fmadd_ps(frac, _mm256_sub_ps(s2.sig, s.sig), s.sig), two);
    clear2 = _mm256_blendv_ps(clear2, s2.clear, two);
    busy2 = s2.busy;
  }
  __m256 lit, k;
  int any = s.busy | busy2;
  composite(q, st, act, near, sd, D, &s, clear2, any, &lit, &k);
  if (b->rec && any) record8(b, lit, k, p, d, ax, two, frac, s.busy, busy2);
  /* Every cone stops after GI_CONE_MAX_STEPS steps, as the scalar one. */
  st->act = _mm256_and_ps(st->act, _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(GI_CONE_MAX_STEPS),
                                                                          st->steps)));
}

/* Level spans (gi__level_spans) of up to eight jobs at once, one job
 * per lane: in[d][lane], out[d][lane]. */
static void spans8(const struct gi_cascade *c, const gi_cone_job *jobs, int count, float in[][LANES],
                   float out[][LANES]) {
  float o[3][LANES], w[3][LANES];
  for (int l = 0; l < LANES; l++)
    for (int a = 0; a < 3; a++) {
      const gi_cone_job *j = &jobs[l < count ? l : 0];
      o[a][l] = j->o[a], w[a][l] = j->w[a];
    }
  __m256 ov[3], inv[3], zero[3];
  for (int a = 0; a < 3; a++) {
    ov[a] = _mm256_loadu_ps(o[a]);
    __m256 wa = _mm256_loadu_ps(w[a]);
    inv[a] = _mm256_div_ps(V1(1.f), wa);
    zero[a] = CMP(wa, _mm256_setzero_ps(), _CMP_EQ_OQ);
  }
  for (int d = 0; d < c->n; d++) {
    const gi_level *L = &c->lv[d];
    float bd = (float)L->s;
    __m256 tin = V1(-INFINITY), tout = V1(INFINITY);
    for (int a = 0; a < 3; a++) {
      __m256 lo = V1(L->lo[a] + bd), hi = V1(L->hi[a] - bd);
      __m256 t0 = _mm256_mul_ps(_mm256_sub_ps(lo, ov[a]), inv[a]), t1 = _mm256_mul_ps(_mm256_sub_ps(hi, ov[a]), inv[a]);
      tin = _mm256_blendv_ps(_mm256_max_ps(tin, _mm256_min_ps(t0, t1)), tin, zero[a]);
      tout = _mm256_blendv_ps(_mm256_min_ps(tout, _mm256_max_ps(t0, t1)), tout, zero[a]);
      /* Parallel to this axis: the whole ray is in or out of the slab. */
      __m256 inside = _mm256_and_ps(CMP(ov[a], lo, _CMP_GE_OQ), CMP(ov[a], hi, _CMP_LE_OQ));
      __m256 miss = _mm256_andnot_ps(inside, zero[a]);
      tin = _mm256_blendv_ps(tin, V1(INFINITY), miss);
      tout = _mm256_blendv_ps(tout, V1(-INFINITY), miss);
    }
    _mm256_storeu_ps(in[d], tin);
    _mm256_storeu_ps(out[d], tout);
  }
}

/* Puts job j (number `index`) into lane l: its start, its constants, its
 * spans (from spans8's group), a fresh march. */
static void lane_load(batch *b, int l, const gi_cone_job *j, int index, const float (*gin)[LANES],
                      const float (*gout)[LANES]) {
  const float *w = j->w;
  int surf = j->h0 >= 0, gl = index & (LANES - 1);
  for (int a = 0; a < 3; a++) {
    float across = surf ? 1 - j->n[a] * j->n[a] : 1.f;
    b->o[a][l] = j->o[a];
    b->w[a][l] = w[a];
    b->iw[a][l] = 1.f / fabsf(w[a]); /* inf for 0: that axis never ends a run */
    b->fb[l][a] = face_lane(a, w[a] > 0);
    b->k[l][a] = fabsf(w[a]); /* a face's projected area, as the scalar kernel */
    b->kax[l][a] = fabsf(w[a]) * across;
    b->L[a][l] = 0;
  }
  b->faces[l] = (uint8_t)((w[0] > 0) | (w[1] > 0) << 1 | (w[2] > 0) << 2);
  b->nw[l] = surf ? gi__dot(j->n, w) : 0.f;
  b->h0[l] = j->h0;
  for (int d = 0; d < b->n; d++) b->span_in[d][l] = gin[d][gl], b->span_out[d][l] = gout[d][gl];
  b->t[l] = j->t0;
  b->a[l] = b->occ[l] = 0;
  b->samples[l] = b->steps[l] = 0;
  b->job[l] = index;
  b->live[l] = 1.f;
}

#define LOADV(dst, src) dst = _mm256_loadu_ps(src)
#define STOREV(dst, src) _mm256_storeu_ps(dst, src)

static void lanes_to_regs(const batch *b, state8 *st) {
  for (int a = 0; a < 3; a++) LOADV(st->o[a], b->o[a]), LOADV(st->w[a], b->w[a]), LOADV(st->iw[a], b->iw[a]),
                            LOADV(st->L[a], b->L[a]);
  LOADV(st->nw, b->nw), LOADV(st->h0, b->h0), LOADV(st->t, b->t), LOADV(st->a, b->a), LOADV(st->occ, b->occ);
  st->samples = _mm256_loadu_si256((const __m256i *)b->samples);
  st->steps = _mm256_loadu_si256((const __m256i *)b->steps);
  st->act = CMP(_mm256_loadu_ps(b->live), V1(0.5f), _CMP_GT_OQ);
}

static void regs_to_lanes(const state8 *st, batch *b) {
  for (int a = 0; a < 3; a++) STOREV(b->L[a], st->L[a]);
  STOREV(b->t, st->t), STOREV(b->a, st->a), STOREV(b->occ, st->occ);
  _mm256_storeu_si256((__m256i *)b->samples, st->samples);
  _mm256_storeu_si256((__m256i *)b->steps, st->steps);
}

/* Writes lane l's finished cone to its job's slot. */
static void lane_finish(const batch *b, int l, gi_cone_out *out) {
  gi_cone_out *o = &out[b->job[l]];
  float a = b->a[l];
  /* A cone stopped by opacity: renormalised by a (march_kernel.c). */
  for (int ch = 0; ch < 3; ch++) o->L[ch] = a >= GI_OPAQUE_ALPHA ? b->L[ch][l] / a : b->L[ch][l];
  o->alpha = a;
  o->occlusion = b->occ[l];
  o->samples = (uint32_t)b->samples[l];
}

/* The batch's level tables. */
static void batch_init(batch *b, const struct gi_cascade *c) {
  b->c = c;
  b->n = c->n;
  b->R = c->R;
  for (int d = 0; d < TAB; d++) {
    const gi_level *L = &c->lv[d < c->n ? d : 0];
    b->s[d] = (float)L->s;
    b->inv[d] = (float)(1.0 / L->s);
    for (int a = 0; a < 3; a++) b->lo[a][d] = L->lo[a], b->slot0[a][d] = L->slot0[a];
    b->rad[d] = (const char *)L->rad;
    b->busy[d] = L->busy;
    b->busy4[d] = L->busy4;
  }
}

/* The level spans of the group of eight jobs now entering lanes: jobs
 * enter in order and lane_load copies a job's spans into its lane, so
 * one group's are enough, and a batch may hold any number of jobs (a
 * batch drains its lanes at its end: the more jobs, the less idling). */
typedef struct {
  int group;
  float in[GI_MAX_LEVELS][LANES], out[GI_MAX_LEVELS][LANES];
} span_group;

static void load_job(const struct gi_cascade *c, batch *b, int l, const gi_cone_job *jobs, int count, int j,
                     span_group *sg) {
  if (j / LANES != sg->group) {
    sg->group = j / LANES;
    spans8(c, jobs + sg->group * LANES, count - sg->group * LANES, sg->in, sg->out);
  }
  lane_load(b, l, &jobs[j], j, (const float(*)[LANES])sg->in, (const float(*)[LANES])sg->out);
}

static void march_jobs(const struct gi_cascade *c, const gi_cone_job *jobs, int count, const par8 *q,
                       gi_cone_out *out, gi_tap_rec *rec) {
  batch b;
  batch_init(&b, c);
  b.rec = rec;
  span_group sg = {.group = -1};
  /* Idle lanes hold a copy of job 0 that nobody reads. */
  int next = 0;
  for (int l = 0; l < LANES; l++) {
    load_job(c, &b, l, jobs, count, next < count ? next : 0, &sg);
    if (next < count) next++;
    else b.live[l] = 0;
  }
  state8 st;
  lanes_to_regs(&b, &st);
  int busy = _mm256_movemask_ps(st.act);
  while (busy) {
    step8(&b, q, &st);
    int done = busy & ~_mm256_movemask_ps(st.act);
    if (!done) continue;
    regs_to_lanes(&st, &b);
    for (; done; done &= done - 1) {
      int l = __builtin_ctz((unsigned)done);
      lane_finish(&b, l, out);
      if (next < count) {
        load_job(c, &b, l, jobs, count, next, &sg);
        next++;
      } else {
        b.live[l] = 0, busy &= ~(1 << l);
      }
    }
    lanes_to_regs(&b, &st);
  }
}

void gi__cone_march_jobs_v3(const struct gi_cascade *c, const gi_cone_job *jobs, int count, float tan_half,
                            float step, float ao_lambda, gi_cone_out *out, gi_tap_rec *rec) {
  float s0 = (float)c->s0;
  par8 q = {tan_half, step, ao_lambda, s0, 1.f / s0, 1.f / (GI_SURFACE_LOD_K * s0)};
  if (count > 0) march_jobs(c, jobs, count, &q, out, rec);
}

/* Level d's sample of a tap as sample8_at and read_lane take it, times
 * rad_scale: the cell as locate finds it, the eight corners summed in
 * their order, each axis's face weighted in read_lane's order. */
static inline __attribute__((always_inline)) __m256 tap_sample8(const struct gi_cascade *c, const float (*lo)[4],
                                                                 const float *inv, const int32_t (*slot0)[4], int d,
                                                                 const float *p, const float *k, int faces) {
  const int R = c->R;
  const __m128i zero = _mm_setzero_si128(), Rv = _mm_set1_epi32(R), Rm2 = _mm_set1_epi32(R - 2);
  const __m128i stride = _mm_setr_epi32(1, R, R * R, 0);
  const __m256i ix = _mm256_setr_epi32(0, 4, 0, 4, 0, 4, 0, 4), iy = _mm256_setr_epi32(1, 1, 5, 5, 1, 1, 5, 5);
  const __m256i iz = _mm256_setr_epi32(2, 2, 2, 2, 6, 6, 6, 6);
  __m128 u = _mm_sub_ps(_mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(p), _mm_loadu_ps(lo[d])), _mm_set1_ps(inv[d])),
                        _mm_set1_ps(0.5f));
  __m128 fl = _mm_floor_ps(u);
  __m128i i0 = _mm_cvttps_epi32(fl);
  __m128 low = _mm_castsi128_ps(_mm_cmpgt_epi32(zero, i0)), high = _mm_castsi128_ps(_mm_cmpgt_epi32(i0, Rm2));
  i0 = _mm_min_epi32(_mm_max_epi32(i0, zero), Rm2);
  fl = _mm_blendv_ps(fl, _mm_setzero_ps(), low);
  u = _mm_blendv_ps(u, _mm_max_ps(u, _mm_setzero_ps()), low);
  fl = _mm_blendv_ps(fl, _mm_set1_ps((float)(R - 2)), high);
  u = _mm_blendv_ps(u, _mm_min_ps(u, _mm_set1_ps((float)(R - 1))), high);
  __m128 f = _mm_sub_ps(u, fl);
  __m128i s0 = _mm_add_epi32(_mm_loadu_si128((const __m128i *)slot0[d]), i0);
  s0 = _mm_sub_epi32(s0, _mm_andnot_si128(_mm_cmpgt_epi32(Rv, s0), Rv));
  __m128i s1 = _mm_add_epi32(s0, _mm_set1_epi32(1));
  s1 = _mm_andnot_si128(_mm_cmpeq_epi32(s1, Rv), s1);
  /* Corner i = dx + 2 dy + 4 dz: its byte offset, and its weight (x y) z as locate's. */
  __m256i off = _mm256_set_m128i(_mm_mullo_epi32(s1, stride), _mm_mullo_epi32(s0, stride));
  __m256i o = _mm256_add_epi32(_mm256_add_epi32(_mm256_permutevar8x32_epi32(off, iz),
                                                _mm256_permutevar8x32_epi32(off, iy)),
                               _mm256_permutevar8x32_epi32(off, ix));
  o = _mm256_mullo_epi32(o, _mm256_set1_epi32((int)sizeof(gi_vrad)));
  __m256 g = _mm256_set_m128(f, _mm_sub_ps(_mm_set1_ps(1.f), f));
  __m256 w = _mm256_mul_ps(_mm256_mul_ps(_mm256_permutevar8x32_ps(g, ix), _mm256_permutevar8x32_ps(g, iy)),
                           _mm256_permutevar8x32_ps(g, iz));
  float wt[8];
  uint32_t co[8];
  _mm256_storeu_ps(wt, w);
  _mm256_storeu_si256((__m256i *)co, o);
  int fb[3];
  for (int a = 0; a < 3; a++) fb[a] = face_lane(a, faces >> a & 1);
  __m256 T[3], a2;
  texel_faces((const char *)c->lv[d].rad, co, wt, 1, fb, T, &a2);
  __m256 P = faces_radiance(k, T);
  return _mm256_mul_ps(P, V1(c->rad_scale));
}

/* gi__replay_tape in lanes 0-2: the eight-lane march's arithmetic for
 * one lane, step by step (step8, composite, lane_finish). */
size_t gi__replay_tape_lanes(const struct gi_cascade *c, const gi_tape_unit *u, size_t units, float L[][3],
                             uint16_t *job) {
  float lo[GI_MAX_LEVELS][4], inv[GI_MAX_LEVELS];
  int32_t slot0[GI_MAX_LEVELS][4];
  for (int d = 0; d < c->n; d++) {
    const gi_level *lv = &c->lv[d];
    inv[d] = (float)(1.0 / lv->s);
    for (int a = 0; a < 3; a++) lo[d][a] = lv->lo[a], slot0[d][a] = lv->slot0[a];
    lo[d][3] = 0, slot0[d][3] = 0;
  }
  size_t cone = 0;
  for (size_t w = 0; w < units;) {
    const gi_tape_unit *h = &u[w];
    const float *k0, *k1;
    unsigned n = gi__tape_cone(u, &w, &k0, &k1);
    __m256 acc = _mm256_setzero_ps();
    for (unsigned q = 0; q < n; q++) {
      const gi_tape_unit *x = &u[w++];
      int fl = x->tap.flags, d = x->tap.d;
      const float *k = fl & GI_TAP_KALT ? k1 : k0;
      __m256 P = fl & GI_TAP_BUSY ? tap_sample8(c, lo, inv, slot0, d, x->tap.p, k, fl) : _mm256_setzero_ps();
      if (fl & GI_TAP_BLEND) {
        float frac = u[w++].f[0];
        __m256 P2 = fl & GI_TAP_BUSY2 ? tap_sample8(c, lo, inv, slot0, d + 1, x->tap.p, k, fl) : _mm256_setzero_ps();
        P = _mm256_fmadd_ps(V1(frac), _mm256_sub_ps(P2, P), P);
      }
      acc = _mm256_fmadd_ps(V1(x->tap.kk), P, acc);
    }
    float v[8], a = h->head.alpha;
    _mm256_storeu_ps(v, acc);
    for (int ch = 0; ch < 3; ch++) L[cone][ch] = a >= GI_OPAQUE_ALPHA ? v[ch] / a : v[ch];
    if (job) job[cone] = h->head.job;
    cone++;
  }
  return cone;
}
