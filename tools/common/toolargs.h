/* toolargs.h: the command-line helpers every gi-* tool shares (gi_toolargs).
 *
 * One rule for numbers on every tool's command line:
 *
 *   integer  -?(0|[1-9][0-9]*)        decimal, no leading zeros; the whole string, in range
 *   number   -?(D+(.D*)?|.D+)([eE][+-]?D+)?   plain decimal, finite
 *   list     number,number,...        exactly n numbers, no blanks
 *
 * So a sign may only be '-' (never '+'), and blanks, hex ("0x10"), "inf",
 * "nan", trailing bytes ("5x", "1,2,3,") and values out of range ("1e999",
 * 2^63, "13" for 1..12) are all refused. A number whose conversion sets
 * ERANGE (overflow or underflow, "1e999" or "1e-400") is refused too. This is
 * a subset of what the HTTP contract (proto/request.c) accepts, so anything
 * gi-client lets through reaches the server in a form it parses.
 *
 * Two layers: ta_parse_* only say whether a string is valid (for callers
 * that try several forms); the option-level helpers (ta_int, ta_double, ...)
 * also print "PROG: OPT: expected WHAT, got 'S'" and "Try 'PROG --help'." and
 * return TA_EXIT_USAGE, so a tool can `return` their result directly. */
#ifndef GI_TOOLARGS_H
#define GI_TOOLARGS_H

#include <getopt.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

/* Exit codes shared by the tools: 0 success, 1 the work failed, 2 usage. */
enum { TA_EXIT_RUN = 1, TA_EXIT_USAGE = 2 };

typedef enum ta_status {
  TA_OK = 0,
  TA_EMPTY,   /* "" */
  TA_SYNTAX,  /* not the grammar above: "+5", " 5", "0x10", "nan", "5x" */
  TA_RANGE,   /* well-formed but out of range: overflow, ERANGE, < lo, > hi */
} ta_status;

/* Pure parsers: no output; *out is written only on TA_OK. */
ta_status ta_parse_ll(const char *s, long long lo, long long hi, long long *out);
ta_status ta_parse_u64(const char *s, uint64_t *out);
ta_status ta_parse_double(const char *s, double *out);
/* Exactly n numbers separated by single commas. */
ta_status ta_parse_doubles(const char *s, double *out, int n);

/* The tools' note for a scene file read with the default y up that looks
 * z-up (gi_scene_looks_z_up), after "PROG: note: <the scene> is flat along z". */
#define TA_NOTE_Z_UP_FIX "but read with y up (the default): if z is up, as in OpenStreetMap and GIS exports, pass --up z"

/* Where a tool's messages go, and the last one (for tests). */
typedef struct ta_ctx {
  const char *prog;  /* "gi-bake": prefixes every message */
  FILE *err;         /* NULL: stderr */
  int quiet;         /* 1: store the message in msg only */
  char msg[640];     /* the last message, "OPT: ..." without the program name */
} ta_ctx;

#define TA_CTX(prog) {(prog), NULL, 0, {0}}

/* Prints "PROG: OPT: <fmt>" and "Try 'PROG --help'."; returns TA_EXIT_USAGE.
 * opt may be NULL (then no "OPT: "). */
int ta_fail(ta_ctx *c, const char *opt, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* The same without the "Try" line, returning rc (files that cannot be read). */
int ta_error(ta_ctx *c, int rc, const char *opt, const char *fmt, ...) __attribute__((format(printf, 4, 5)));

/* Option-level parsers: 0 on success, else TA_EXIT_USAGE after
 * "OPT: expected WHAT, got 'S'". what = NULL gives the default
 * ("an integer in LO..HI", "an unsigned 64-bit integer", "a finite number",
 * "N finite numbers separated by commas"). */
int ta_int(ta_ctx *c, const char *opt, const char *what, const char *s, int lo, int hi, int *out);
int ta_ll(ta_ctx *c, const char *opt, const char *what, const char *s, long long lo, long long hi, long long *out);
int ta_u64(ta_ctx *c, const char *opt, const char *what, const char *s, uint64_t *out);
/* A finite number v with above < v <= at_most (use -HUGE_VAL / HUGE_VAL for none);
 * what (may be NULL: the bounds are named instead) describes it in the error. */
int ta_double(ta_ctx *c, const char *opt, const char *what, const char *s, double above, double at_most,
              double *out);
int ta_doubles(ta_ctx *c, const char *opt, const char *what, const char *s, int n, double *out);
/* "X,Y,Z": three finite numbers. */
int ta_triple(ta_ctx *c, const char *opt, const char *s, double out[3]);

/* After getopt_long returned ':' (an option without its value) or '?' (an
 * unknown option; also an argument given to a flag), names the option:
 * "option '--at' needs a value", "unknown option '-x'". Returns TA_EXIT_USAGE. */
int ta_getopt_fail(ta_ctx *c, int ret, char **argv, const struct option *long_opts);

/* A long option that takes a value, given a second time: the second value
 * would silently replace the first ('--exr a.exr --exr b.exr' wrote b.exr
 * only). Call with each option getopt_long returns; `repeatable` lists the
 * vals that may repeat (lights, effects), ended by 0; `seen` has one byte
 * per entry of long_opts, zeroed by the caller. Returns 0, or
 * TA_EXIT_USAGE after "--NAME: given twice (it takes one value)". Flags
 * without a value may repeat: a second --json changes nothing. */
int ta_once(ta_ctx *c, const struct option *long_opts, int val, const int *repeatable, unsigned char *seen);

/* outpath.c: an output file the user named, checked before slow work: its
 * folder must exist and be writable, and it must not be a folder. *path
 * becomes the path to give the writers (which write "<path>.tmp.<pid>"
 * and rename it into place): a symlink's target, or for a device or FIFO
 * (/dev/stdout, also spelt "-") a private temporary file that
 * ta_outputs_finish copies into it. The strings live until ta_outputs_finish. A SIGINT, SIGTERM,
 * SIGHUP or SIGPIPE then removes the outputs' temporary files before the
 * process dies of it; temporaries of a plain output left by a process that
 * is gone (kill -9) are removed now (ta_remove_stale). Returns 0, TA_EXIT_USAGE (empty name, a folder) or
 * TA_EXIT_RUN. Main thread only. */
int ta_check_output(ta_ctx *c, const char *opt, const char **path);
/* 0 when no output checked so far is the existing file `input` (what
 * names it: "scene file"); else TA_EXIT_USAGE, naming both: the rename
 * into place would replace an input the run reads (gi-bake box.obj --exr
 * box.obj wrote its EXR over the scene). Main thread only. */
int ta_check_outputs_spare(ta_ctx *c, const char *what, const char *input);
/* TA_EXIT_USAGE after "OPT: 'path' is also the --X output" when path (a
 * folder or file the run writes other than through ta_check_output, such
 * as gi-bake's --resume folder) names an output checked so far; else 0. */
int ta_check_not_output(ta_ctx *c, const char *opt, const char *path);
/* Removes from folder dir the temporary files "<name>.tmp.<pid>" (and
 * older releases' "<name>.tmp.<pid>.tmp.<pid>") that a killed process left:
 * those whose <name> (its first len bytes) owns() accepts and whose
 * process is gone (kill(pid, 0) fails with ESRCH: a folder shared with
 * another machine's processes is not for this). Says each on stderr
 * (without a prefix option); returns how many. ta_check_output does this
 * for each plain output file. */
size_t ta_remove_stale(ta_ctx *c, const char *dir, int (*owns)(const char *name, size_t len, const void *arg),
                       const void *arg);
/* A temporary file that is not an output's, being written now: a SIGINT,
 * SIGTERM, SIGHUP or SIGPIPE removes it too until ta_scratch_end. -1 when
 * the name is too long (then it is not watched). Main thread only. */
int ta_scratch_begin(const char *path);
void ta_scratch_end(void);
/* Whether path (as ta_check_output returned it) stands for a device or FIFO. */
int ta_output_is_special(const char *path);
/* Whether an output is this process's standard output (--exr /dev/stdout):
 * a tool then prints its report elsewhere, so the stream holds the file alone. */
int ta_output_is_stdout(void);
/* At the end of a run: when ok, copies each special output that was
 * written into its device or FIFO; always removes the temporary files and
 * frees the paths. Returns 0, or TA_EXIT_RUN when a copy failed. */
int ta_outputs_finish(ta_ctx *c, int ok);

/* Creates folder path and its parents as needed (mode 0777 less the
 * umask), as mkdir -p. Returns 0, or TA_EXIT_RUN with the folder and
 * errno's reason said. */
int ta_mkdirs(ta_ctx *c, const char *opt, const char *path);

/* One step of a path file: its time (seconds) and viewpoint. */
typedef struct ta_step {
  double t;
  double at[3];
} ta_step;
/* Longest path line read; longer is an error naming the line. */
#define TA_PATH_LINE_MAX 512
/* Reads a path file: one 't,x,y,z' per line (blanks around fields, '#'
 * comments, CRLF, an optional first line of four column names such as
 * "t,x,y,z"), t in seconds and not decreasing. *out is malloc'ed (the
 * caller frees it). Returns 0, TA_EXIT_USAGE (a bad line, named by file and
 * number; no steps) or TA_EXIT_RUN (cannot read, out of memory). */
int ta_read_path(ta_ctx *c, const char *opt, const char *path, ta_step **out, size_t *n);

/* Reads a points file (gi_points.h: one 'x y z' per line, '#' comments) of
 * at most max points. Returns 0, TA_EXIT_USAGE (a bad line, named by file
 * and number, or too many) or TA_EXIT_RUN (cannot read). */
int ta_read_points(ta_ctx *c, const char *opt, const char *path, size_t max, double **pts, size_t *n);

/* GI_CPU_PATH (gi/gi_cpu.h) before anything else: 0 when it is unset or a
 * path this process can run, else TA_EXIT_USAGE after "PROG: GI_CPU_PATH=...
 * is not recognised: expected ...". A tool that went on would time or bake
 * on a path the user did not ask for. */
int ta_check_cpu_path(ta_ctx *c);

/* A one-shot tool's malloc keeps the blocks it frees for its later ones
 * instead of returning them to the kernel (mempolicy.c says why). Call it
 * first in main, before anything allocates. Not for long-lived processes. */
void ta_memory_policy(void);

/* "VERSION (GIT_REV)" of this build. */
const char *ta_version(void);
/* FNV-1a (64 bits) of n bytes at p, continuing from h: the tools' cache
 * keys and bake hashes. */
uint64_t ta_fnv(uint64_t h, const void *p, size_t n);
/* ta_fnv over the bytes of the file at path (h unchanged when it cannot
 * be read: the caller has read it already or will fail on it). */
uint64_t ta_fnv_file(uint64_t h, const char *path);

#endif
