/* jobs.c: probe lists too long for one answer.
 *
 * A job runs on its own runner threads (max_jobs of them), never on the
 * bake workers, so a city-wide probe list cannot starve interactive
 * requests; and it bakes its cascades privately, so it cannot evict the
 * cascades interactive clients are using. Progress is counted per tile.
 * The result is an EXR in tmp_dir, kept until max_jobs_retained newer
 * jobs have finished; then the oldest finished job and its file go. */
#define _POSIX_C_SOURCE 200809L
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include "server.h"

typedef struct job {
  gi_proto_job st;          /* guarded by the table's mutex */
  const gs_scene *scene;
  gi_quality req, q;         /* as requested (for the bake), resolved (for tiles) */
  gi_proto_probes p;        /* owned */
  double t_start;
  char path[1200];          /* result file when done */
  uint64_t order;           /* submission order, for retention */
  struct job *next;
} job;

struct gs_jobs {
  gs_service *svc;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  job *all;                 /* every retained job */
  int queued, stop;
  uint64_t order;
  int nthreads;
  pthread_t threads[64];
};

static void random_id(char id[40]) {
  unsigned char b[12] = {0};
  FILE *f = fopen("/dev/urandom", "rb");
  size_t n = f ? fread(b, 1, sizeof b, f) : 0;
  if (f) fclose(f);
  if (n != sizeof b) {
    /* No urandom (a bare chroot): time and address still give unique ids. */
    uint64_t x = (uint64_t)(gs_now_ms() * 1e3) ^ (uint64_t)(uintptr_t)id;
    memcpy(b, &x, 8);
  }
  for (size_t i = 0; i < sizeof b; i++) snprintf(id + 2 * i, 3, "%02x", b[i]);
}

typedef struct {
  gs_jobs *j;
  job *jb;
} prog_ctx;

static void on_tile(void *ctx, size_t tile, size_t probes) {
  prog_ctx *pc = ctx;
  pthread_mutex_lock(&pc->j->mu);
  pc->jb->st.tiles_done = (int)tile + 1;
  pc->jb->st.probes_done += probes;
  pc->jb->st.elapsed_s = (gs_now_ms() - pc->jb->t_start) * 1e-3;
  pthread_mutex_unlock(&pc->j->mu);
}

/* Drops the oldest finished jobs beyond the retention limit. Locked. */
static void retire(gs_jobs *j) {
  int finished = 0;
  for (job *b = j->all; b; b = b->next) finished += b->st.state >= GI_JOB_DONE;
  while (finished > j->svc->cfg->max_jobs_retained) {
    job **pp = NULL, **it;
    for (it = &j->all; *it; it = &(*it)->next)
      if ((*it)->st.state >= GI_JOB_DONE && (!pp || (*it)->order < (*pp)->order)) pp = it;
    if (!pp) break;
    job *old = *pp;
    *pp = old->next;
    if (old->path[0]) unlink(old->path);
    gi_proto_probes_free(&old->p);
    free(old);
    finished--;
  }
}

static void run_job(gs_jobs *j, job *jb) {
  gs_service *svc = j->svc;
  gi_error_info e = {0};
  gs_tile *tiles = NULL;
  size_t nt = 0;
  gi_probe *pr = malloc(jb->p.num_points * sizeof *pr);
  gi_result rc = GI_ERR_NOMEM;
  snprintf(e.msg, sizeof e.msg, "job: out of memory for %zu probes", jb->p.num_points);
  if (pr && gs_tiles_make(jb->scene, &jb->q, jb->p.points, jb->p.num_points, &tiles, &nt) == 0) {
    pthread_mutex_lock(&j->mu);
    jb->st.tiles = (int)nt;
    pthread_mutex_unlock(&j->mu);
    prog_ctx pc = {j, jb};
    gi_bake_report rep;
    e.msg[0] = 0;
    rc = gs_gather_tiles(svc, jb->scene, &jb->req, &jb->q, jb->p.points, tiles, nt, 0, pr, &rep, NULL, NULL, on_tile, &pc, &e);
    if (rc == GI_OK) {
      char path[1200], ntiles[32];
      gs_tmp_path(svc, ".exr", path, sizeof path);
      snprintf(ntiles, sizeof ntiles, "%zu", nt);
      gi_exr_extra extra[] = {{"gi.job", jb->st.id}, {"gi.tiles", ntiles}};
      rc = gi_probes_write_exr_ex(path, pr, jb->p.num_points, jb->scene->scene, tiles[0].at, &rep, jb->p.bake.half,
                                  extra, 2, &e);
      if (rc == GI_OK) snprintf(jb->path, sizeof jb->path, "%s", path);
    }
  }
  free(pr);
  gs_tiles_free(tiles, nt);
  pthread_mutex_lock(&j->mu);
  jb->st.elapsed_s = (gs_now_ms() - jb->t_start) * 1e-3;
  if (rc == GI_OK) {
    jb->st.state = GI_JOB_DONE;
  } else {
    jb->st.state = GI_JOB_FAILED;
    gi_proto_fail(&jb->st.error, gs_status_of(rc), "%s", e.msg[0] ? e.msg : gi_strerror(rc));
  }
  /* The points are no longer needed; a retained job keeps only its status. */
  gi_proto_probes_free(&jb->p);
  retire(j);
  pthread_mutex_unlock(&j->mu);
}

static void *runner(void *p) {
  gs_jobs *j = p;
  pthread_mutex_lock(&j->mu);
  for (;;) {
    job *next = NULL;
    while (!j->stop) {
      /* Oldest queued job first. */
      for (job *b = j->all; b; b = b->next)
        if (b->st.state == GI_JOB_QUEUED && (!next || b->order < next->order)) next = b;
      if (next) break;
      pthread_cond_wait(&j->cv, &j->mu);
    }
    if (j->stop) break;
    next->st.state = GI_JOB_RUNNING;
    next->t_start = gs_now_ms();
    j->queued--;
    pthread_mutex_unlock(&j->mu);
    run_job(j, next);
    pthread_mutex_lock(&j->mu);
  }
  pthread_mutex_unlock(&j->mu);
  return NULL;
}

gs_jobs *gs_jobs_new(gs_service *svc) {
  gs_jobs *j = calloc(1, sizeof *j);
  if (!j) return NULL;
  j->svc = svc;
  pthread_mutex_init(&j->mu, NULL);
  pthread_cond_init(&j->cv, NULL);
  int n = svc->cfg->max_jobs < 64 ? svc->cfg->max_jobs : 64;
  for (int i = 0; i < n; i++)
    if (pthread_create(&j->threads[j->nthreads], NULL, runner, j) == 0) j->nthreads++;
  if (!j->nthreads) {
    gs_jobs_free(j);
    return NULL;
  }
  return j;
}

void gs_jobs_free(gs_jobs *j) {
  if (!j) return;
  pthread_mutex_lock(&j->mu);
  j->stop = 1;
  pthread_cond_broadcast(&j->cv);
  pthread_mutex_unlock(&j->mu);
  /* A running job finishes its bake first: the core cannot be interrupted. */
  for (int i = 0; i < j->nthreads; i++) pthread_join(j->threads[i], NULL);
  for (job *b = j->all, *n; b; b = n) {
    n = b->next;
    if (b->path[0]) unlink(b->path);
    gi_proto_probes_free(&b->p);
    free(b);
  }
  pthread_mutex_destroy(&j->mu);
  pthread_cond_destroy(&j->cv);
  free(j);
}

int gs_jobs_submit(gs_jobs *j, const gs_scene *s, gi_proto_probes *p, const gi_quality *req, const gi_quality *q,
                   char id[40],
                   gi_proto_error *err) {
  pthread_mutex_lock(&j->mu);
  if (j->queued >= j->svc->cfg->max_jobs_queued) {
    pthread_mutex_unlock(&j->mu);
    return gi_proto_fail(err, 503, "jobs: %d jobs are already queued; retry later", j->queued);
  }
  job *jb = calloc(1, sizeof *jb);
  if (!jb) {
    pthread_mutex_unlock(&j->mu);
    return gi_proto_fail(err, 503, "jobs: out of memory");
  }
  random_id(jb->st.id);
  jb->st.state = GI_JOB_QUEUED;
  jb->st.probes = p->num_points;
  jb->scene = s;
  jb->req = *req;
  jb->q = *q;
  jb->p = *p;
  memset(p, 0, sizeof *p); /* the job owns the points now */
  jb->t_start = gs_now_ms();
  jb->order = ++j->order;
  jb->next = j->all;
  j->all = jb;
  j->queued++;
  snprintf(id, 40, "%s", jb->st.id);
  pthread_cond_signal(&j->cv);
  pthread_mutex_unlock(&j->mu);
  return 0;
}

static job *find(gs_jobs *j, const char *id) {
  for (job *b = j->all; b; b = b->next)
    if (!strcmp(b->st.id, id)) return b;
  return NULL;
}

void gs_jobs_status(gs_jobs *j, const char *id, gs_answer *a) {
  pthread_mutex_lock(&j->mu);
  job *b = find(j, id);
  if (b) {
    gi_proto_job st = b->st;
    if (st.state == GI_JOB_RUNNING || st.state == GI_JOB_QUEUED) st.elapsed_s = (gs_now_ms() - b->t_start) * 1e-3;
    pthread_mutex_unlock(&j->mu);
    a->status = 200;
    a->json = gi_proto_job_json(&st);
    a->content_type = "application/json";
    return;
  }
  pthread_mutex_unlock(&j->mu);
  gi_proto_error pe;
  gi_proto_fail(&pe, 404, "job '%.40s' is unknown (finished jobs are kept for a limited number of newer jobs)", id);
  gs_answer_error(a, &pe);
}

void gs_jobs_result(gs_jobs *j, const char *id, gs_answer *a) {
  gi_proto_error pe;
  pthread_mutex_lock(&j->mu);
  job *b = find(j, id);
  if (!b) {
    pthread_mutex_unlock(&j->mu);
    gi_proto_fail(&pe, 404, "job '%.40s' is unknown", id);
    return gs_answer_error(a, &pe);
  }
  if (b->st.state != GI_JOB_DONE) {
    gi_proto_job_state s = b->st.state;
    pthread_mutex_unlock(&j->mu);
    if (s == GI_JOB_FAILED) gi_proto_fail(&pe, 409, "job '%s' failed: %s", id, b->st.error.message);
    else gi_proto_fail(&pe, 409, "job '%s' is %s; poll /v1/jobs/%s", id, gi_proto_job_state_name(s), id);
    return gs_answer_error(a, &pe);
  }
  /* Opened under the lock: retirement cannot unlink it in between. */
  int fd = open(b->path, O_RDONLY | O_CLOEXEC);
  pthread_mutex_unlock(&j->mu);
  struct stat st;
  if (fd < 0 || fstat(fd, &st) != 0) {
    if (fd >= 0) close(fd);
    gi_proto_fail(&pe, 500, "job '%s': its result file is gone", id);
    return gs_answer_error(a, &pe);
  }
  a->status = 200;
  a->fd = fd;
  a->size = (size_t)st.st_size;
  a->content_type = "image/x-exr";
  snprintf(a->disposition, sizeof a->disposition, "attachment; filename=\"probes-%s.exr\"", id);
}

void gs_jobs_count(gs_jobs *j, int by_state[4]) {
  memset(by_state, 0, 4 * sizeof(int));
  pthread_mutex_lock(&j->mu);
  for (job *b = j->all; b; b = b->next)
    if ((unsigned)b->st.state < 4) by_state[b->st.state]++;
  pthread_mutex_unlock(&j->mu);
}
