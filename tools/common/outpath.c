/* outpath.c: the output files a user names on a command line.
 *
 * Every writer puts its file at "<path>.tmp.<pid>" and renames it into
 * place, so a reader never sees half a file. A rename replaces whatever
 * the name is: a symlink would become a plain file (the file it pointed
 * at left stale), and a device or a FIFO would be replaced by a file (as
 * root, `--exr /dev/null` broke /dev/null for the whole machine). So a
 * symlink is followed to the file it names, and a device, FIFO or socket
 * gets a private temporary file that is copied into it once the run has
 * succeeded (`--exr /dev/stdout | ...` works). On SIGINT, SIGTERM, SIGHUP
 * or SIGPIPE (a reader gone) the temporary files of the named outputs are
 * removed before the process dies as the signal says (and a scratch file
 * named by ta_scratch_begin). A kill -9 cannot be caught: a later run
 * removes the temporaries of its outputs whose process is gone. Not
 * thread-safe: tools call these from their main thread. */
#define _XOPEN_SOURCE 700 /* realpath */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include "toolargs.h"

#define TA_MAX_OUTPUTS 16

typedef struct {
  char *write;          /* the path writers get (owned) */
  char *special;        /* a device or FIFO to copy into after success, or NULL (owned) */
  char *dir;            /* the private folder holding `write` for a special output (owned) */
  char sig_tmp[PATH_MAX + 32]; /* the writer's "<write>.tmp.<pid>", removed on a signal */
  char *canon;          /* `write` with its folder resolved, for a plain file; else NULL (owned) */
  const char *opt;      /* the option that named it */
} ta_output;

static ta_output outs[TA_MAX_OUTPUTS];
static volatile sig_atomic_t num_outs;
/* A temporary file being written that is not an output's (a --resume
 * tile): its name, valid while scratch_set is 1. */
static char scratch[PATH_MAX + 64];
static volatile sig_atomic_t scratch_set;

/* Removes what a killed run leaves (async-signal-safe calls only), then
 * dies of the same signal. */
static void on_signal(int sig) {
  for (int i = 0; i < num_outs; i++) {
    unlink(outs[i].sig_tmp);
    if (outs[i].special) unlink(outs[i].write), rmdir(outs[i].dir);
  }
  if (scratch_set) unlink(scratch);
  signal(sig, SIG_DFL);
  raise(sig);
}

static void watch_signals(void) {
  struct sigaction sa, old;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  static const int sigs[] = {SIGINT, SIGTERM, SIGHUP, SIGPIPE};
  for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
    /* A signal the parent ignores (nohup) stays ignored. */
    if (sigaction(sigs[i], NULL, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    sigaction(sigs[i], &sa, NULL);
  }
}

/* The file a symlink chain names: realpath when it exists, else the last
 * link's text resolved against its folder (a link to a file not written
 * yet). NULL when out of memory or the chain is broken further up. */
static char *follow_link(const char *path) {
  char *r = realpath(path, NULL);
  if (r) return r;
  char target[PATH_MAX];
  ssize_t n = readlink(path, target, sizeof target - 1);
  if (n <= 0) return NULL;
  target[n] = '\0';
  if (target[0] == '/') return strdup(target);
  char *copy = strdup(path);
  if (!copy) return NULL;
  const char *d = dirname(copy);
  size_t len = strlen(d) + 1 + (size_t)n + 1;
  char *out = malloc(len);
  if (out) snprintf(out, len, "%s/%s", d, target);
  free(copy);
  return out;
}

/* The folder of path must exist and take new files. */
static int check_folder(ta_ctx *c, const char *opt, const char *path, const char *named) {
  char *dir = strdup(path);
  if (!dir) return ta_error(c, TA_EXIT_RUN, opt, "out of memory");
  const char *d = dirname(dir);
  int rc = 0;
  if (access(d, W_OK | X_OK) != 0)
    rc = ta_error(c, TA_EXIT_RUN, opt, "cannot write into '%s' for '%s': %s", d, named, strerror(errno));
  free(dir);
  return rc;
}

/* path with its folder resolved (realpath), so "a.exr" and "./a.exr" compare equal. */
static char *canonical(const char *path) {
  char *copy = strdup(path), *copy2 = strdup(path);
  char *dir = copy ? realpath(dirname(copy), NULL) : NULL;
  const char *base = copy2 ? basename(copy2) : NULL;
  char *out = NULL;
  if (dir && base) {
    size_t len = strlen(dir) + 1 + strlen(base) + 1;
    if ((out = malloc(len))) snprintf(out, len, "%s/%s", dir, base);
  }
  free(copy), free(copy2), free(dir);
  return out;
}

/* A private folder and file for special output `dev` (its name's last part kept). */
static int special_file(ta_ctx *c, const char *opt, const char *dev, ta_output *o) {
  const char *tmpdir = getenv("TMPDIR");
  char tmpl[PATH_MAX];
  snprintf(tmpl, sizeof tmpl, "%s/gi-out.XXXXXX", tmpdir && *tmpdir ? tmpdir : "/tmp");
  if (!mkdtemp(tmpl)) return ta_error(c, TA_EXIT_RUN, opt, "cannot make a folder in '%s' for '%s': %s",
                                     tmpdir && *tmpdir ? tmpdir : "/tmp", dev, strerror(errno));
  char *copy = strdup(dev);
  const char *base = copy ? strrchr(copy, '/') : NULL;
  base = base ? base + 1 : copy;
  size_t len = strlen(tmpl) + 1 + (base ? strlen(base) : 0) + 1;
  o->dir = strdup(tmpl);
  o->write = malloc(len);
  o->special = strdup(dev);
  if (o->write && base) snprintf(o->write, len, "%s/%s", tmpl, base);
  free(copy);
  if (!o->dir || !o->write || !o->special || !base) return ta_error(c, TA_EXIT_RUN, opt, "out of memory");
  return 0;
}

/* The pid of name's temporary suffix ".tmp.<pid>" (twice in older
 * releases' "<out>.tmp.<pid>.tmp.<pid>"), and the length of the name before
 * it; 0 when name has no such suffix. */
static long temp_owner(const char *name, size_t *stem) {
  long pid = 0;
  size_t n = strlen(name);
  for (int k = 0; k < 2; k++) {
    size_t d = n;
    while (d > 0 && name[d - 1] >= '0' && name[d - 1] <= '9') d--;
    if (d == n || n - d > 9 || d < 6 || strncmp(name + d - 5, ".tmp.", 5) || name[d] == '0') break;
    long p = strtol(name + d, NULL, 10);
    if (pid && p != pid) break; /* a doubled name carries one pid twice */
    pid = p, n = d - 5;
  }
  *stem = n;
  return pid;
}

size_t ta_remove_stale(ta_ctx *c, const char *dir, int (*owns)(const char *name, size_t len, const void *arg),
                       const void *arg) {
  DIR *d = opendir(dir);
  if (!d) return 0;
  size_t removed = 0;
  struct dirent *e;
  while ((e = readdir(d))) {
    size_t stem;
    long pid = temp_owner(e->d_name, &stem);
    /* Only a process that is gone: ESRCH (EPERM is another user's, alive). */
    if (pid <= 0 || pid == (long)getpid() || !owns(e->d_name, stem, arg) || kill((pid_t)pid, 0) == 0 ||
        errno != ESRCH)
      continue;
    char path[PATH_MAX];
    if (snprintf(path, sizeof path, "%s/%s", dir, e->d_name) >= (int)sizeof path) continue;
    struct stat st;
    if (lstat(path, &st) != 0 || !S_ISREG(st.st_mode) || unlink(path) != 0) continue;
    removed++;
    ta_error(c, 0, NULL, "removed '%s', a temporary file left by process %ld, which is gone", path, pid);
  }
  closedir(d);
  return removed;
}

/* An output's own temporaries: its base name exactly. */
static int owns_base(const char *name, size_t len, const void *arg) {
  return strlen((const char *)arg) == len && !strncmp(name, (const char *)arg, len);
}

static void remove_stale_of(ta_ctx *c, const char *path) {
  char *a = strdup(path), *b = strdup(path);
  if (a && b) ta_remove_stale(c, dirname(a), owns_base, basename(b));
  free(a), free(b);
}

int ta_check_output(ta_ctx *c, const char *opt, const char **path) {
  if (!**path) return ta_fail(c, opt, "expected a file name, got ''");
  /* "-" is standard output, as for curl -o - (a file of that name is ./-):
   * gi-client -o - wrote a file named '-'. */
  if (!strcmp(*path, "-")) *path = "/dev/stdout";
  if (num_outs == TA_MAX_OUTPUTS) return ta_error(c, TA_EXIT_RUN, opt, "more than %d outputs", TA_MAX_OUTPUTS);
  ta_output *o = &outs[num_outs];
  memset(o, 0, sizeof *o);
  struct stat st;
  const char *p = *path;
  if (lstat(p, &st) == 0 && S_ISLNK(st.st_mode)) {
    if (!(o->write = follow_link(p))) return ta_error(c, TA_EXIT_RUN, opt, "cannot follow the link '%s'", p);
    p = o->write;
  }
  int rc = 0;
  if (stat(p, &st) == 0 && S_ISDIR(st.st_mode)) {
    rc = ta_fail(c, opt, "'%s' is a folder; expected a file name", *path);
  } else if (stat(p, &st) == 0 && !S_ISREG(st.st_mode)) {
    char *resolved = o->write;
    o->write = NULL;
    rc = special_file(c, opt, p, o);
    free(resolved);
  } else if (!(rc = check_folder(c, opt, p, *path)) && !o->write && !(o->write = strdup(p))) {
    rc = ta_error(c, TA_EXIT_RUN, opt, "out of memory");
  }
  /* Two outputs on one plain file: the second rename would replace the first
   * output and the run would still say it wrote both. */
  if (!rc && !o->special && (o->canon = canonical(o->write)))
    for (int i = 0; i < num_outs; i++)
      if (outs[i].canon && !strcmp(outs[i].canon, o->canon)) {
        rc = ta_fail(c, opt, "'%s' is also the %s output; each output needs a file of its own", *path, outs[i].opt);
        break;
      }
  if (rc) {
    if (o->dir) rmdir(o->dir);
    free(o->write), free(o->special), free(o->dir), free(o->canon);
    return rc;
  }
  o->opt = opt;
  snprintf(o->sig_tmp, sizeof o->sig_tmp, "%s.tmp.%d", o->write, (int)getpid());
  if (num_outs == 0 && !scratch_set) watch_signals();
  num_outs++;
  *path = o->write;
  if (!o->special) remove_stale_of(c, o->write);
  return 0;
}

int ta_scratch_begin(const char *path) {
  scratch_set = 0;
  if (strlen(path) >= sizeof scratch) return -1;
  strcpy(scratch, path);
  if (num_outs == 0) watch_signals(); /* again is harmless: the same handler */
  scratch_set = 1;
  return 0;
}

void ta_scratch_end(void) { scratch_set = 0; }

int ta_check_not_output(ta_ctx *c, const char *opt, const char *path) {
  char *canon = canonical(path);
  struct stat sp, so;
  int have = stat(path, &sp) == 0, rc = 0;
  for (int i = 0; i < num_outs && !rc; i++) {
    const ta_output *o = &outs[i];
    if ((canon && o->canon && !strcmp(canon, o->canon)) ||
        (have && !o->special && stat(o->write, &so) == 0 && so.st_dev == sp.st_dev && so.st_ino == sp.st_ino))
      rc = ta_fail(c, opt, "'%s' is also the %s output; give each its own name", path, o->opt);
  }
  free(canon);
  return rc;
}

int ta_check_outputs_spare(ta_ctx *c, const char *what, const char *input) {
  struct stat si, so;
  if (!input || stat(input, &si) != 0 || !S_ISREG(si.st_mode)) return 0;
  for (int i = 0; i < num_outs; i++)
    if (!outs[i].special && stat(outs[i].write, &so) == 0 && so.st_dev == si.st_dev && so.st_ino == si.st_ino)
      return ta_fail(c, outs[i].opt, "'%s' is also the %s '%s'; write the output elsewhere", outs[i].write, what,
                     input);
  return 0;
}

int ta_output_is_special(const char *path) {
  for (int i = 0; i < num_outs; i++)
    if (outs[i].special && !strcmp(outs[i].write, path)) return 1;
  return 0;
}

int ta_output_is_stdout(void) {
  struct stat out, st;
  if (fstat(STDOUT_FILENO, &out) != 0) return 0;
  for (int i = 0; i < num_outs; i++)
    if (outs[i].special && stat(outs[i].special, &st) == 0 && st.st_dev == out.st_dev && st.st_ino == out.st_ino)
      return 1;
  return 0;
}

/* Copies file `from` into the device or FIFO `to`. 0, or errno. */
static int copy_into(const char *from, const char *to) {
  int in = open(from, O_RDONLY), out = in < 0 ? -1 : open(to, O_WRONLY | O_NOCTTY);
  int e = in < 0 || out < 0 ? errno : 0;
  char buf[1 << 16];
  ssize_t n = 0;
  while (!e && (n = read(in, buf, sizeof buf)) > 0)
    for (ssize_t off = 0; off < n && !e;) {
      ssize_t w = write(out, buf + off, (size_t)(n - off));
      if (w < 0 && errno != EINTR) e = errno;
      off += w > 0 ? w : 0;
    }
  if (!e && n < 0) e = errno;
  if (in >= 0) close(in);
  if (out >= 0 && close(out) != 0 && !e) e = errno;
  return e;
}

int ta_outputs_finish(ta_ctx *c, int ok) {
  int rc = 0;
  for (int i = 0; i < num_outs; i++) {
    ta_output *o = &outs[i];
    if (o->special) {
      struct stat st;
      /* An output the run did not write (a failed run, an unused name) is not copied. */
      int e = ok && stat(o->write, &st) == 0 ? copy_into(o->write, o->special) : 0;
      if (e && !rc) rc = ta_error(c, TA_EXIT_RUN, NULL, "cannot copy the output into '%s': %s", o->special, strerror(e));
      unlink(o->write);
      rmdir(o->dir);
    }
  }
  /* No signal may read the list while it is freed. */
  int n = num_outs;
  num_outs = 0;
  for (int i = 0; i < n; i++) free(outs[i].write), free(outs[i].special), free(outs[i].dir), free(outs[i].canon);
  return rc;
}
