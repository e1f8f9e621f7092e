/* test_workload.c: the arithmetic of gi-accuracy's workloads at equal
 * error (tools/gi-accuracy/metrics.c) against hand-computed values.
 *
 * The sweep below has error falling as 1 / sqrt(time), as a path tracer's
 * does: (10 ms, 40%), (40 ms, 20%), (160 ms, 10%). Log-log interpolation
 * is then exact: the time at error e between two counts is
 * t0 (e0 / e)^2. The crossover is the smallest count N with
 * N * path > bake + N * answer. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include "metrics.h"

static const double ms[3] = {10, 40, 160}, mre[3] = {0.4, 0.2, 0.1};

static void test_equal_error(void **state) {
  int how = 7;
  /* Halfway in log between 10 and 40 ms: error 0.4 / sqrt 2, time sqrt(10 * 40) = 20. */
  assert_true(fabs(acc_ms_at_error(ms, mre, 3, 0.4 / sqrt(2.0), &how) - 20) < 1e-9);
  assert_int_equal(how, 0);
  /* 15%: 40 (0.2 / 0.15)^2 = 71.111... */
  assert_true(fabs(acc_ms_at_error(ms, mre, 3, 0.15, &how) - 640.0 / 9) < 1e-9);
  assert_int_equal(how, 0);
  /* Exactly a measured error: that count's time. */
  assert_true(fabs(acc_ms_at_error(ms, mre, 3, 0.2, &how) - 40) < 1e-9);
  assert_int_equal(how, 0);
  /* The first count already better: its time, an upper bound. */
  assert_true(acc_ms_at_error(ms, mre, 3, 0.5, &how) == 10);
  assert_int_equal(how, 1);
  /* Never reached: the last time, a lower bound. */
  assert_true(acc_ms_at_error(ms, mre, 3, 0.05, &how) == 160);
  assert_int_equal(how, -1);
  assert_true(acc_ms_at_error(ms, mre, 0, 0.05, &how) == 0);
  assert_int_equal(how, -1);
  /* Not monotone (a noisy reference floor): the first crossing counts,
   * between (10, 0.4) and (40, 0.1): 10 (0.4 / 0.2)^(log 4 / log 4) = 20. */
  const double bumpy[3] = {0.4, 0.1, 0.3};
  assert_true(fabs(acc_ms_at_error(ms, bumpy, 3, 0.2, &how) - 20) < 1e-9);
  assert_int_equal(how, 0);
  /* A flat stretch at the target: the later count's time, no division by zero. */
  const double flat[3] = {0.3, 0.2, 0.2};
  assert_true(fabs(acc_ms_at_error(ms, flat, 3, 0.2, &how) - 40) < 1e-9);
}

static void test_crossover(void **state) {
  /* bake 1000 ms, answer 0.1 ms, path 2.1 ms a query: a gain of 2 ms a
   * query; 500 queries tie (1050 = 1000 + 50), 501 win. */
  assert_true(acc_crossover(1000, 0.1, 2.1) == 501);
  /* A gain of 3: 1000 / 3 = 333.3; 334 * 3.1 = 1035.4 > 1033.4, 333 * 3.1 = 1032.3 < 1033.3. */
  assert_true(acc_crossover(1000, 0.1, 3.1) == 334);
  /* A path tracer no dearer than the answer: the bake never pays off. */
  assert_true(isinf(acc_crossover(1000, 0.5, 0.5)));
  assert_true(isinf(acc_crossover(1000, 0.5, 0.2)));
  /* No bake to pay for: the first query wins. */
  assert_true(acc_crossover(0, 0.1, 0.2) == 1);
  /* Issue 11's aerial view, as quoted: bake 3000 + render 800 ms against
   * the path tracer's 1050 ms: 3000 / 250 = 12 views tie, 13 win. */
  assert_true(acc_crossover(3000, 800, 1050) == 13);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_equal_error),
      cmocka_unit_test(test_crossover),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
