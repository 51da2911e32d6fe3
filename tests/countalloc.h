/*
 * countalloc.h - the counting allocator of the tests that prove real-time
 * code allocates nothing.  A test file includes it once: it defines malloc
 * and its kin for the whole program (the voices a test loads included),
 * forwarding to glibc's, and counts in ca_allocs the calls made while
 * ca_in_rt is set on the calling thread.  ThreadSanitizer and
 * AddressSanitizer bring their own malloc: under them nothing is defined
 * and CA_COUNTING is 0 (the count stays 0; tests of the counter skip).
 */
#ifndef TESTS_COUNTALLOC_H
#define TESTS_COUNTALLOC_H

#include <stddef.h>

#if defined(__SANITIZE_THREAD__) || defined(__SANITIZE_ADDRESS__)
#define CA_COUNTING 0
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer) || __has_feature(address_sanitizer)
#define CA_COUNTING 0
#endif
#endif
#ifndef CA_COUNTING
#define CA_COUNTING 1
#endif

/* volatile: the compiler may not move these stores across a call it
 * knows as the builtin malloc */
static __thread volatile int ca_in_rt;
static volatile long ca_allocs;

#if CA_COUNTING
extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void *__libc_memalign(size_t, size_t);
extern void __libc_free(void *);

static void ca_count(void) {
    if (ca_in_rt)
        __atomic_add_fetch(&ca_allocs, 1, __ATOMIC_RELAXED);
}
void *malloc(size_t n) {
    ca_count();
    return __libc_malloc(n);
}
void *calloc(size_t a, size_t b) {
    ca_count();
    return __libc_calloc(a, b);
}
void *realloc(void *p, size_t n) {
    ca_count();
    return __libc_realloc(p, n);
}
void *aligned_alloc(size_t al, size_t n) {
    ca_count();
    return __libc_memalign(al, n);
}
int posix_memalign(void **p, size_t al, size_t n) {
    ca_count();
    *p = __libc_memalign(al, n);
    return *p ? 0 : 12;
}
void free(void *p) {
    ca_count();
    __libc_free(p);
}
#endif

/* A cmocka test that the counter counts: a malloc inside the marked
 * region is seen, so a count of zero elsewhere means something.  For
 * files that include cmocka.h before this header. */
#ifdef cmocka_unit_test
#if defined(__GNUC__)
__attribute__((unused))
#endif
static void ca_test_counter_counts(void **s) {
    (void)s;
    if (!CA_COUNTING)
        skip();
    ca_allocs = 0;
    ca_in_rt = 1;
    void *volatile p = malloc(16);
    ca_in_rt = 0;
    free(p);
    assert_int_equal(ca_allocs, 1);
}
#endif

#endif
