/*
 * What one lockstep round trip between a DUT and the session costs the transport alone (bench, not a
 * test): the decision "shared memory and a futex in place of the socket" needs this number.
 *
 * A child ("the DUT") sends a 32-byte request and waits for a 32-byte reply, N times; the parent ("the
 * session") waits for each request and replies at once. Each round trip is timed in the child
 * (CLOCK_MONOTONIC), and the median and 99th percentile printed, for each transport:
 *   socket        a Unix stream socketpair, blocking recv on both sides (the shim's side as it is)
 *   socket+epoll  the same, the session waiting in epoll_wait before its recv (rig/lockstep/pump.c)
 *   futex         a shared page: a sequence word each way, FUTEX_WAIT and FUTEX_WAKE
 *   spin+futex    the same, each side spinning up to SPIN_NS on the word before it sleeps
 * and each placement: both on one core (as lockstep pins them: rig/session.py) and a core each.
 *
 *     build/bench/roundtrip [N]      (make build/bench/roundtrip; make bench runs it)
 */
#define _GNU_SOURCE
#include <linux/futex.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define MSG 32
#define SPIN_NS 20000

enum transport { SOCKET, SOCKET_EPOLL, FUTEX, SPIN_FUTEX, TRANSPORTS };
static const char *const NAMES[TRANSPORTS] = { "socket", "socket+epoll", "futex", "spin+futex" };

struct page {
    _Atomic uint32_t req, rep; /* sequence numbers: a request, its reply */
    uint8_t msg[MSG];
    int64_t took_ns[]; /* the child's round trips */
};

static int64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static void pin(int cpu)
{
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    if (sched_setaffinity(0, sizeof set, &set) != 0) {
        perror("sched_setaffinity");
        exit(2);
    }
}

/* until *word != seen: spinning up to spin_ns first, then FUTEX_WAIT */
static void await_change(_Atomic uint32_t *word, uint32_t seen, int64_t spin_ns)
{
    if (spin_ns) {
        int64_t until = now_ns() + spin_ns;
        while (atomic_load_explicit(word, memory_order_acquire) == seen && now_ns() < until)
            __builtin_ia32_pause();
    }
    while (atomic_load_explicit(word, memory_order_acquire) == seen)
        syscall(SYS_futex, word, FUTEX_WAIT, seen, NULL, NULL, 0);
}

static void bump(_Atomic uint32_t *word)
{
    atomic_fetch_add_explicit(word, 1, memory_order_release);
    syscall(SYS_futex, word, FUTEX_WAKE, 1, NULL, NULL, 0);
}

static void full(int fd, uint8_t *buf, int send_it)
{
    for (size_t done = 0; done < MSG;) {
        ssize_t k = send_it ? send(fd, buf + done, MSG - done, 0) : recv(fd, buf + done, MSG - done, 0);
        if (k <= 0) {
            perror(send_it ? "send" : "recv");
            exit(2);
        }
        done += (size_t)k;
    }
}

static void dut(enum transport t, struct page *p, int fd, int n)
{
    uint8_t buf[MSG] = { 1 };
    for (int i = 0; i < n; i++) {
        int64_t t0 = now_ns();
        if (t == SOCKET || t == SOCKET_EPOLL) {
            full(fd, buf, 1);
            full(fd, buf, 0);
        } else {
            memcpy(p->msg, buf, MSG);
            uint32_t rep = atomic_load(&p->rep);
            bump(&p->req);
            await_change(&p->rep, rep, t == SPIN_FUTEX ? SPIN_NS : 0);
            memcpy(buf, p->msg, MSG);
        }
        p->took_ns[i] = now_ns() - t0;
    }
}

static void session(enum transport t, struct page *p, int fd, int n)
{
    uint8_t buf[MSG];
    int ep = -1;
    if (t == SOCKET_EPOLL) {
        ep = epoll_create1(0);
        struct epoll_event ev = { .events = EPOLLIN, .data.fd = fd };
        epoll_ctl(ep, EPOLL_CTL_ADD, fd, &ev);
    }
    uint32_t req = 0;
    for (int i = 0; i < n; i++) {
        if (t == SOCKET || t == SOCKET_EPOLL) {
            struct epoll_event ev;
            if (ep >= 0)
                while (epoll_wait(ep, &ev, 1, -1) != 1)
                    ;
            full(fd, buf, 0);
            full(fd, buf, 1);
        } else {
            await_change(&p->req, req, t == SPIN_FUTEX ? SPIN_NS : 0);
            req = atomic_load(&p->req);
            p->msg[0]++;
            bump(&p->rep);
        }
    }
    if (ep >= 0)
        close(ep);
}

static int by_value(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

static void measure(enum transport t, int one_core, int n)
{
    size_t size = sizeof(struct page) + (size_t)n * sizeof(int64_t);
    struct page *p = mmap(NULL, size, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    int sv[2];
    if (p == MAP_FAILED || socketpair(AF_UNIX, SOCK_STREAM, 0, sv) != 0) {
        perror("mmap/socketpair");
        exit(2);
    }
    pid_t child = fork();
    if (child == 0) {
        pin(one_core ? 0 : 1);
        dut(t, p, sv[1], n);
        _exit(0);
    }
    pin(0);
    session(t, p, sv[0], n);
    int status;
    waitpid(child, &status, 0);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        fprintf(stderr, "%s: the child failed\n", NAMES[t]);
        exit(2);
    }
    qsort(p->took_ns, (size_t)n, sizeof(int64_t), by_value);
    printf("%-13s %-9s %8.1f %8.1f\n", NAMES[t], one_core ? "one core" : "two cores", p->took_ns[n / 2] / 1e3,
           p->took_ns[(int)(0.99 * (n - 1))] / 1e3);
    close(sv[0]);
    close(sv[1]);
    munmap(p, size);
}

int main(int argc, char **argv)
{
    int n = argc > 1 ? atoi(argv[1]) : 20000;
    if (n < 100) {
        fprintf(stderr, "usage: roundtrip [N >= 100]\n");
        return 2;
    }
    int two = sysconf(_SC_NPROCESSORS_ONLN) > 1;
    printf("round trips of %d bytes each way, %d of each (us)\ntransport     placement   median      p99\n", MSG, n);
    for (int one_core = 1; one_core >= !two; one_core--)
        for (int t = 0; t < TRANSPORTS; t++)
            measure((enum transport)t, one_core, n);
    return 0;
}
