/*
 * semihost.h - Arm semihosting calls (the debugger or QEMU performs them for the target).
 *
 * Each call is "bkpt 0xAB" with the operation in r0 and a pointer to its argument block in r1;
 * the result comes back in r0. Only what firmware.c needs: open, read, close, write0 (a string
 * to the host's console) and exit.
 */
#ifndef SEMIHOST_H
#define SEMIHOST_H

#include <stdint.h>
#include <string.h>

#define SH_OPEN 0x01
#define SH_CLOSE 0x02
#define SH_WRITE0 0x04
#define SH_READ 0x06
#define SH_EXIT 0x18
#define SH_MODE_RB 1                       /* fopen mode "rb" */
#define SH_EXIT_OK 0x20026                 /* ADP_Stopped_ApplicationExit: QEMU exits 0 */
#define SH_EXIT_ERROR 0x20023              /* ADP_Stopped_RunTimeErrorUnknown: QEMU exits 1 */

static inline uint32_t sh_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

/* Open a host file; returns a handle, or -1. */
static inline int32_t sh_open(const char *path, uint32_t mode)
{
    uint32_t a[3];
    a[0] = (uint32_t)(uintptr_t)path;
    a[1] = mode;
    a[2] = (uint32_t)strlen(path);
    return (int32_t)sh_call(SH_OPEN, a);
}

/* Read n bytes; returns the number of bytes NOT read (0: all read). */
static inline uint32_t sh_read(int32_t handle, void *buf, uint32_t n)
{
    uint32_t a[3];
    a[0] = (uint32_t)handle;
    a[1] = (uint32_t)(uintptr_t)buf;
    a[2] = n;
    return sh_call(SH_READ, a);
}

static inline void sh_close(int32_t handle)
{
    uint32_t a[1];
    a[0] = (uint32_t)handle;
    (void)sh_call(SH_CLOSE, a);
}

/* Write a NUL-terminated string to the host console. */
static inline void sh_write0(const char *s) { (void)sh_call(SH_WRITE0, s); }

static inline void sh_exit(int ok)
{
    (void)sh_call(SH_EXIT, (const void *)(uintptr_t)(ok ? SH_EXIT_OK : SH_EXIT_ERROR));
    for (;;) {
    }
}

#endif /* SEMIHOST_H */
