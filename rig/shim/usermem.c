/*
 * The caller's memory, copied as the kernel copies it (copy_from_user/copy_to_user): a bad pointer
 * handed to an emulated device is EFAULT, never a crash inside the shim. Part of rigshim.c (one
 * translation unit): see its top comment.
 */

/* The kernel copies a caller's memory with copy_from_user/copy_to_user: a bad address is EFAULT, never
   a crash. The shim does the same with process_vm_readv/process_vm_writev on its own pid (always
   allowed on oneself), every piece of one transfer in one call, so a transfer costs a syscall or two
   more, not one per buffer. Where those are not available (ENOSYS, or EPERM from a seccomp filter)
   it says so once and copies with memcpy, rejecting only addresses no user mapping has.
   Pieces that lie in the calling thread's live stack, between the shim's own frame and the stack's
   top, are mapped and writable whatever they hold, so they are copied with memcpy and cost nothing:
   a C driver's arguments, messages and buffers are usually there (the reference FC's all are, which
   saves it 4600 syscalls per 2 s of flight). A frame outside the thread's stack (a signal handler on
   an alternate stack, a coroutine's stack) takes the checked path. */
static int uaccess_memcpy;
static __thread uintptr_t stack_lo, stack_hi; /* this thread's stack, asked once (0, 0: unknown) */
static __thread int stack_asked;

static int on_live_stack(const struct iovec *remote, size_t nr)
{
    char here; /* in the shim's frame: the caller's live frames are all above it */
    if (!stack_asked) {
        stack_asked = 1;
        pthread_attr_t attr;
        void *addr;
        size_t size;
        if (pthread_getattr_np(pthread_self(), &attr) == 0) {
            if (pthread_attr_getstack(&attr, &addr, &size) == 0) {
                stack_lo = (uintptr_t)addr;
                stack_hi = (uintptr_t)addr + size;
            }
            pthread_attr_destroy(&attr);
        }
    }
    uintptr_t sp = (uintptr_t)&here;
    if (sp < stack_lo || sp >= stack_hi)
        return 0;
    for (size_t i = 0; i < nr; i++) {
        uintptr_t a = (uintptr_t)remote[i].iov_base;
        if (remote[i].iov_len && (a < sp || a + remote[i].iov_len < a || a + remote[i].iov_len > stack_hi))
            return 0;
    }
    return 1;
}

static int user_range(const void *p, size_t n)
{
    uintptr_t a = (uintptr_t)p;
    return n == 0 || (a >= 4096 && a + n > a && a + n <= (uintptr_t)1 << 47);
}

static size_t copy_by_memcpy(const struct iovec *local, size_t nl, const struct iovec *remote, size_t nr, int to_user)
{
    size_t li = 0, loff = 0;
    for (size_t i = 0; i < nr; i++) {
        if (!user_range(remote[i].iov_base, remote[i].iov_len))
            return i;
        for (size_t roff = 0; roff < remote[i].iov_len;) {
            while (li < nl && loff == local[li].iov_len) {
                li++;
                loff = 0;
            }
            if (li == nl)
                return i;
            size_t k = remote[i].iov_len - roff < local[li].iov_len - loff ? remote[i].iov_len - roff
                                                                           : local[li].iov_len - loff;
            char *r = (char *)remote[i].iov_base + roff, *l = (char *)local[li].iov_base + loff;
            memcpy(to_user ? r : l, to_user ? l : r, k);
            roff += k;
            loff += k;
        }
    }
    return nr;
}

/* Copies the caller's pieces (remote) into the shim's (local, the same bytes in total) or, to_user,
   back. Returns how many remote pieces, from the first, were copied whole: nr when all were. */
static size_t user_copy(const struct iovec *local, size_t nl, const struct iovec *remote, size_t nr, int to_user)
{
    size_t total = 0;
    for (size_t i = 0; i < nr; i++)
        total += remote[i].iov_len;
    if (total == 0)
        return nr;
    if (on_live_stack(remote, nr))
        return copy_by_memcpy(local, nl, remote, nr, to_user);
    if (!__atomic_load_n(&uaccess_memcpy, __ATOMIC_RELAXED)) {
        ssize_t k = to_user ? process_vm_writev(own_pid, local, nl, remote, nr, 0)
                            : process_vm_readv(own_pid, local, nl, remote, nr, 0);
        if (k >= 0 || (errno != ENOSYS && errno != EPERM)) {
            size_t done = k < 0 ? 0 : (size_t)k, i = 0;
            while (i < nr && remote[i].iov_len <= done)
                done -= remote[i++].iov_len;
            return i;
        }
        int err = errno;
        __atomic_store_n(&uaccess_memcpy, 1, __ATOMIC_RELAXED);
        note("process_vm_readv/writev refused (%s): the shim copies with memcpy, so a bad pointer handed to an "
             "emulated device may crash the command where the kernel says EFAULT",
             strerror(err));
    }
    return copy_by_memcpy(local, nl, remote, nr, to_user);
}

/* One piece: 0 or EFAULT. */
static int copy_in(void *dst, const void *user, size_t n)
{
    struct iovec l = { dst, n }, r = { (void *)user, n };
    return user_copy(&l, 1, &r, 1, 0) == 1 ? 0 : EFAULT;
}

static int copy_out(void *user, const void *src, size_t n)
{
    struct iovec l = { (void *)src, n }, r = { user, n };
    return user_copy(&l, 1, &r, 1, 1) == 1 ? 0 : EFAULT;
}

/* i2c-dev's read() and write() move at most 8192 bytes; sysfs takes at most a page per write, copied
   in before the attribute looks at it. The caller's buffer is copied as the kernel copies it. */
#define SYSFS_PAGE 4096
static __thread unsigned char xfer_buf[SYSFS_PAGE > MAX_XFER ? SYSFS_PAGE : MAX_XFER];
