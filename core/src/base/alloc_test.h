/* alloc_test.h: the allocation counters and failure injection of
 * base/alloc.c. Only tests include this; the core never arms a failure. */
#ifndef GI_ALLOC_TEST_H
#define GI_ALLOC_TEST_H

/* Makes the n-th core allocation from now fail (0 = the next one), once;
 * -1 disarms. Thread-safe. */
void gi__alloc_fail_after(long n);
/* 1 while an armed failure has not been reached yet. */
int gi__alloc_fail_armed(void);
/* Successful allocations minus frees since the program started. */
long gi__alloc_live(void);
/* Allocation calls since the program started, failed ones included. */
long gi__alloc_attempts(void);

#endif
