/* jobs.c: probe lists too long for one answer.
 *
 * A job runs on its own runner threads (max_jobs of them), never on the
 * bake workers, so a city-wide probe list cannot starve interactive
 * requests; and it bakes its cascades privately, so they never fill the
 * cache. Its bakes do reserve their bytes in the memory budget (serve.c),
 * which, like any bake, may evict cached cascades no request holds.
 * Progress is counted per tile.
 * The result is an EXR (0600) in the server's private folder in tmp_dir
 * (0700, removed at exit, and at the next start if the server was killed),
 * kept while at most max_jobs_retained finished jobs are; past that the
 * oldest finished job without a result (failed, cancelled) goes first,
 * then the oldest result and its file.
 *
 * A job stops when it is cancelled (DELETE, shutdown) or outlives
 * job_deadline_s: its token (gi_cancel) stops the bake or gather it is in
 * within a chunk's time, since one tile may hold every point of the list
 * and gather for minutes. */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
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
  char effects[200];        /* X-GI-Effects of the result, as an inline answer's */
  uint64_t order;           /* submission order, for retention */
  int cancel;               /* cancelled: DELETE or shutdown (guarded) */
  int timed_out;            /* stopped by job_deadline_s (guarded) */
  gi_cancel *token;         /* stops the bake or gather in flight: DELETE, deadline */
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
  char dir[1100];           /* the private folder, or empty */
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

/* After each tile: progress, then whether to stop (cancelled, or past the deadline). */
static int on_tile(void *ctx, size_t tile, size_t probes, gi_error_info *err) {
  prog_ctx *pc = ctx;
  job *jb = pc->jb;
  double limit = pc->j->svc->cfg->job_deadline_s;
  pthread_mutex_lock(&pc->j->mu);
  jb->st.tiles_done = (int)tile + 1;
  jb->st.probes_done += probes;
  jb->st.elapsed_s = (gs_now_ms() - jb->t_start) * 1e-3;
  if (!jb->cancel && jb->st.elapsed_s > limit) jb->timed_out = 1;
  int stop = jb->cancel || jb->timed_out;
  pthread_mutex_unlock(&pc->j->mu);
  if (stop && jb->timed_out)
    snprintf(err->msg, sizeof err->msg, "job: stopped after %zu tile(s): it ran longer than the job deadline of %g s",
             tile + 1, limit);
  else if (stop)
    snprintf(err->msg, sizeof err->msg, "job: cancelled after %zu tile(s)", tile + 1);
  return stop;
}

static void job_free(job *b) {
  gi_proto_probes_free(&b->p);
  gi_cancel_free(b->token);
  free(b);
}

/* Whether finished job a goes before b: one without a result (failed,
 * cancelled) before one with a result to fetch, then the older. A client
 * that started and cancelled jobs pushed other clients' unfetched
 * results out, oldest first. */
static int retire_before(const job *a, const job *b) {
  int ra = a->st.state == GI_JOB_DONE, rb = b->st.state == GI_JOB_DONE;
  return ra != rb ? rb : a->order < b->order;
}

/* Drops finished jobs beyond the retention limit (retire_before's order). Locked. */
static void retire(gs_jobs *j) {
  int finished = 0;
  for (job *b = j->all; b; b = b->next) finished += b->st.state >= GI_JOB_DONE;
  while (finished > j->svc->cfg->max_jobs_retained) {
    job **pp = NULL, **it;
    for (it = &j->all; *it; it = &(*it)->next)
      if ((*it)->st.state >= GI_JOB_DONE && (!pp || retire_before(*it, *pp))) pp = it;
    if (!pp) break;
    job *old = *pp;
    *pp = old->next;
    if (old->path[0]) unlink(old->path);
    job_free(old);
    finished--;
  }
}

/* The job's tiles: with 'at', the one cascade the client chose, as an inline
 * answer uses (the points were checked to lie within its reach); else the
 * server's tiles around the points. 0, or -1 out of memory. */
static int job_tiles(const job *jb, gs_tile **out, size_t *nt) {
  if (jb->p.bake.has_at) return gs_tile_around(jb->p.bake.at, jb->p.num_points, out, nt);
  return gs_tiles_make(jb->scene, &jb->q, jb->p.points, jb->p.num_points, out, nt) == 0 && *out ? 0 : -1;
}

static void run_job(gs_jobs *j, job *jb) {
  gs_service *svc = j->svc;
  gi_error_info e = {0};
  gs_tile *tiles = NULL;
  size_t nt = 0;
  gi_probe *pr = malloc(jb->p.num_points * sizeof *pr);
  gi_result rc = GI_ERR_NOMEM;
  snprintf(e.msg, sizeof e.msg, "job: out of memory for %zu probes", jb->p.num_points);
  if (pr && job_tiles(jb, &tiles, &nt) == 0) {
    pthread_mutex_lock(&j->mu);
    jb->st.tiles = (int)nt;
    pthread_mutex_unlock(&j->mu);
    prog_ctx pc = {j, jb};
    gi_bake_report rep;
    gi_timings ms = {0};
    e.msg[0] = 0;
    gi_cancel_set_deadline(jb->token, gi_now_ms() + svc->cfg->job_deadline_s * 1e3);
    rc = gs_gather_tiles(svc, jb->scene, &jb->req, &jb->q, jb->p.points, tiles, nt, 0, NULL, jb->token, pr, &rep,
                         &ms, NULL, on_tile, &pc, &e);
    if (rc == GI_ERR_CANCELLED) {
      /* Stopped inside a tile by the token: said as on_tile says it between tiles. */
      pthread_mutex_lock(&j->mu);
      int done = jb->st.tiles_done;
      if (!jb->cancel) jb->timed_out = 1;
      pthread_mutex_unlock(&j->mu);
      if (jb->timed_out)
        snprintf(e.msg, sizeof e.msg, "job: stopped after %d tile(s): it ran longer than the job deadline of %g s",
                 done, svc->cfg->job_deadline_s);
      else snprintf(e.msg, sizeof e.msg, "job: cancelled after %d tile(s)", done);
    }
    if (rc == GI_OK) {
      /* The header an inline probe list's EXR has (README): the job's stages
       * and its total since it started; its bakes are its own (miss). */
      char path[1200], ntiles[32], timing[320];
      gs_tmp_path(svc, ".exr", path, sizeof path);
      snprintf(ntiles, sizeof ntiles, "%zu", nt);
      gi_proto_server_timing(&ms, gs_now_ms() - jb->t_start, timing, sizeof timing);
      gi_exr_extra extra[] = {{"gi.timings", timing}, {"gi.cache", "miss"}, {"gi.tiles", ntiles},
                              {"gi.job", jb->st.id}};
      rc = gi_probes_write_exr_ex(path, pr, jb->p.num_points, jb->scene->scene, tiles[0].at, &rep, jb->p.bake.half,
                                  extra, 4, &e);
      gi_proto_effects_header(rep.effects, jb->effects, sizeof jb->effects);
      /* The folder is private already; the file is too, for a copy moved out of it. */
      if (rc == GI_OK && chmod(path, S_IRUSR | S_IWUSR) != 0) {
        rc = GI_ERR_IO;
        snprintf(e.msg, sizeof e.msg, "job: cannot make the result private: %s", strerror(errno));
        unlink(path);
      }
      if (rc == GI_OK) snprintf(jb->path, sizeof jb->path, "%s", path);
    }
  }
  free(pr);
  gs_tiles_free(tiles, nt);
  char buf[256];
  const char *msg = rc == GI_OK ? "" : gs_client_message(rc, &e, buf, sizeof buf); /* logs a private path */
  pthread_mutex_lock(&j->mu);
  jb->st.elapsed_s = (gs_now_ms() - jb->t_start) * 1e-3;
  if (rc == GI_OK) {
    jb->st.state = GI_JOB_DONE;
  } else if (jb->cancel) {
    jb->st.state = GI_JOB_CANCELLED;
  } else {
    jb->st.state = GI_JOB_FAILED;
    gi_proto_fail(&jb->st.error, jb->timed_out ? 504 : gs_status_of(rc), "%s", msg);
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

/* ---- the private folder ---------------------------------------------------- */

#define DIR_PREFIX "gi-server-jobs."

/* Removes a folder we own and everything in it, depth first, never
 * following a symbolic link (the link itself goes); 0, or -1 with errno
 * when the folder itself stays. It removed only the regular files, so a
 * stale folder holding a subfolder stayed (and was logged as removed). */
#define GS_REMOVE_MAX_DEPTH 32
static int remove_tree_at(int parent, const char *name, int depth) {
  int fd = openat(parent, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  DIR *d = fd >= 0 ? fdopendir(fd) : NULL;
  if (!d) {
    if (fd >= 0) close(fd);
    return -1;
  }
  for (struct dirent *e; (e = readdir(d));) {
    if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
    struct stat st;
    if (fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0) continue;
    if (!S_ISDIR(st.st_mode)) unlinkat(dirfd(d), e->d_name, 0);
    else if (depth < GS_REMOVE_MAX_DEPTH) remove_tree_at(dirfd(d), e->d_name, depth + 1);
  }
  closedir(d);
  return unlinkat(parent, name, AT_REMOVEDIR);
}

static int remove_folder(const char *path) { return remove_tree_at(AT_FDCWD, path, 0); }

/* Folders "gi-server-jobs.PID.XXXXXX" in tmp_dir whose server (PID) is gone:
 * what a killed server left (results and scratch files). Ours only: same
 * user, real folders, not symbolic links. */
static void remove_stale(const char *tmp_dir) {
  DIR *d = opendir(tmp_dir);
  if (!d) return;
  for (struct dirent *e; (e = readdir(d));) {
    if (strncmp(e->d_name, DIR_PREFIX, strlen(DIR_PREFIX))) continue;
    char *end;
    long pid = strtol(e->d_name + strlen(DIR_PREFIX), &end, 10);
    struct stat st;
    if (*end != '.' || pid <= 0 || pid == (long)getpid()) continue;
    if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* still running (or not ours to ask) */
    if (fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0 || !S_ISDIR(st.st_mode) ||
        st.st_uid != geteuid())
      continue;
    char path[1400];
    snprintf(path, sizeof path, "%s/%s", tmp_dir, e->d_name);
    if (remove_folder(path) == 0)
      fprintf(stderr, "gi-server: removed %s, left by server process %ld which is gone\n", path, pid);
    else
      fprintf(stderr, "gi-server: cannot remove %s, left by server process %ld which is gone: %s\n", path, pid,
              strerror(errno));
  }
  closedir(d);
}

/* mkdtemp makes the folder 0700: results and scratch files are ours alone. */
static int make_private_dir(gs_jobs *j) {
  const char *tmp = j->svc->cfg->tmp_dir[0] ? j->svc->cfg->tmp_dir : "/tmp";
  remove_stale(tmp);
  snprintf(j->dir, sizeof j->dir, "%s/" DIR_PREFIX "%ld.XXXXXX", tmp, (long)getpid());
  if (!mkdtemp(j->dir)) {
    fprintf(stderr, "gi-server: cannot make a private folder in %s: %s\n", tmp, strerror(errno));
    j->dir[0] = 0;
    return -1;
  }
  snprintf(j->svc->work_dir, sizeof j->svc->work_dir, "%s", j->dir);
  return 0;
}

gs_jobs *gs_jobs_new(gs_service *svc) {
  gs_jobs *j = calloc(1, sizeof *j);
  if (!j) return NULL;
  j->svc = svc;
  pthread_mutex_init(&j->mu, NULL);
  pthread_cond_init(&j->cv, NULL);
  if (make_private_dir(j)) {
    gs_jobs_free(j);
    return NULL;
  }
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
  /* A running job stops inside its tile once cancelled (gs_jobs_cancel_all),
   * else finishes. */
  for (int i = 0; i < j->nthreads; i++) pthread_join(j->threads[i], NULL);
  for (job *b = j->all, *n; b; b = n) {
    n = b->next;
    if (b->path[0]) unlink(b->path);
    job_free(b);
  }
  if (j->dir[0]) remove_folder(j->dir);
  j->svc->work_dir[0] = 0;
  pthread_mutex_destroy(&j->mu);
  pthread_cond_destroy(&j->cv);
  free(j);
}

int gs_jobs_submit(gs_jobs *j, const gs_scene *s, gi_proto_probes *p, const gi_quality *req, const gi_quality *q,
                   char id[40],
                   gi_proto_error *err) {
  pthread_mutex_lock(&j->mu);
  /* A job an idle runner takes at once does not wait, so it does not count
   * against max_jobs_queued (as the worker pool's queue): with 0, jobs
   * were refused even with every runner idle. */
  int running = 0;
  for (job *b = j->all; b; b = b->next) running += b->st.state == GI_JOB_RUNNING;
  if (j->queued >= j->svc->cfg->max_jobs_queued + (j->nthreads - running)) {
    pthread_mutex_unlock(&j->mu);
    return gi_proto_fail(err, 503, "jobs: %d jobs are already queued; retry later", j->queued);
  }
  job *jb = calloc(1, sizeof *jb);
  if (!jb || !(jb->token = gi_cancel_new())) {
    free(jb);
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

/* Locks j and finds job id; when it is unknown, unlocks and answers 404. */
static job *find_locked(gs_jobs *j, const char *id, gs_answer *a) {
  pthread_mutex_lock(&j->mu);
  job *b = find(j, id);
  if (b) return b;
  pthread_mutex_unlock(&j->mu);
  gi_proto_error pe;
  gi_proto_fail(&pe, 404, "job '%.40s' is unknown", id);
  gs_answer_error(a, &pe);
  return NULL;
}

void gs_jobs_result(gs_jobs *j, const char *id, gs_answer *a) {
  gi_proto_error pe;
  job *b = find_locked(j, id, a);
  if (!b) return;
  if (b->st.state != GI_JOB_DONE) {
    /* Copied under the lock: once it is released, retire() may free b. */
    gi_proto_job_state s = b->st.state;
    if (s == GI_JOB_FAILED) gi_proto_fail(&pe, 409, "job '%s' failed: %s", id, b->st.error.message);
    else if (s == GI_JOB_CANCELLED) gi_proto_fail(&pe, 409, "job '%s' was cancelled", id);
    else gi_proto_fail(&pe, 409, "job '%s' is %s; poll /v1/jobs/%s", id, gi_proto_job_state_name(s), id);
    pthread_mutex_unlock(&j->mu);
    return gs_answer_error(a, &pe);
  }
  /* Opened under the lock: retirement cannot unlink it in between. */
  int fd = open(b->path, O_RDONLY | O_CLOEXEC);
  snprintf(a->effects, sizeof a->effects, "%s", b->effects);
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

void gs_jobs_count(gs_jobs *j, int by_state[GI_JOB_STATE_COUNT]) {
  memset(by_state, 0, GI_JOB_STATE_COUNT * sizeof(int));
  pthread_mutex_lock(&j->mu);
  for (job *b = j->all; b; b = b->next)
    if ((unsigned)b->st.state < GI_JOB_STATE_COUNT) by_state[b->st.state]++;
  pthread_mutex_unlock(&j->mu);
}

/* A queued job ends now, as cancelled. Locked. */
static void cancel_queued(gs_jobs *j, job *b) {
  b->st.state = GI_JOB_CANCELLED;
  b->st.elapsed_s = (gs_now_ms() - b->t_start) * 1e-3;
  gi_proto_probes_free(&b->p);
  j->queued--;
}

void gs_jobs_cancel(gs_jobs *j, const char *id, gs_answer *a) {
  gi_proto_error pe;
  job *b = find_locked(j, id, a);
  if (!b) return;
  gi_proto_job_state was = b->st.state;
  if (was != GI_JOB_QUEUED && was != GI_JOB_RUNNING) {
    pthread_mutex_unlock(&j->mu);
    gi_proto_fail(&pe, 409, "job '%s' has already finished (%s)", id, gi_proto_job_state_name(was));
    return gs_answer_error(a, &pe);
  }
  if (was == GI_JOB_QUEUED) cancel_queued(j, b);
  else b->cancel = 1, gi_cancel_set(b->token); /* the runner stops within its bake or gather */
  gi_proto_job st = b->st;
  if (was == GI_JOB_RUNNING) st.elapsed_s = (gs_now_ms() - b->t_start) * 1e-3;
  if (was == GI_JOB_QUEUED) retire(j); /* may free b: st is a copy */
  pthread_mutex_unlock(&j->mu);
  a->status = was == GI_JOB_QUEUED ? 200 : 202;
  a->json = gi_proto_job_json(&st);
  a->content_type = "application/json";
}

void gs_jobs_cancel_all(gs_jobs *j) {
  pthread_mutex_lock(&j->mu);
  for (job *b = j->all; b; b = b->next) {
    if (b->st.state == GI_JOB_QUEUED) cancel_queued(j, b);
    else if (b->st.state == GI_JOB_RUNNING) b->cancel = 1, gi_cancel_set(b->token);
  }
  pthread_mutex_unlock(&j->mu);
}

void gs_jobs_abandon(gs_jobs *j) {
  /* No lock: the process is about to exit and a runner may hold it. */
  if (j && j->dir[0]) remove_folder(j->dir);
}
