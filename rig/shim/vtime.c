/*
 * Virtual time (lockstep): the clocks read the shared page's sim time (a clock read costs a quantum,
 * no message), sleeps and the poll family's timeouts ask the session to run the world until the
 * wake-up. Outside lockstep every call here passes through to libc. Part of rigshim.c (one
 * translation unit): see its top comment.
 */

#define NS 1000000000ull

static uint64_t ts_ns(const struct timespec *ts) { return (uint64_t)ts->tv_sec * NS + (uint64_t)ts->tv_nsec; }
static void ns_ts(uint64_t ns, struct timespec *ts)
{
    ts->tv_sec = (time_t)(ns / NS);
    ts->tv_nsec = (long)(ns % NS);
}

static int virtual_clock(clockid_t id) { return active && lockstep && shm && id >= 0; }

/* Base of a clock at sim time 0, or -1 for clocks we leave alone. */
static int64_t clock_base(clockid_t id)
{
    switch (id) {
    case CLOCK_REALTIME:
    case CLOCK_REALTIME_COARSE:
    case CLOCK_TAI:
    case CLOCK_REALTIME_ALARM:
        return (int64_t)shm->epoch_ns;
    case CLOCK_MONOTONIC:
    case CLOCK_MONOTONIC_RAW:
    case CLOCK_MONOTONIC_COARSE:
    case CLOCK_BOOTTIME:
    case CLOCK_BOOTTIME_ALARM:
        return (int64_t)shm->mono_base_ns;
    case CLOCK_PROCESS_CPUTIME_ID:
    case CLOCK_THREAD_CPUTIME_ID:
        return 0; /* a busy program's CPU time is its virtual time */
    default:
        return -1;
    }
}

static uint32_t wait_until(uint64_t wake_ns, uint32_t kind);

/* A time on a static clock (ns since its epoch) as sim time (0: at or before sim time 0). */
static uint64_t sim_time_on(clockid_t id, uint64_t abs_ns)
{
    int64_t base = clock_base(id);
    return base >= 0 && abs_ns > (uint64_t)base ? abs_ns - (uint64_t)base : 0;
}

/* threads.c and vtimers.c, included after this part: the rule for many threads and virtual timers */
static int ruled(void);
static int rule_wait(uint64_t deadline, int (*can_go)(void *), void *arg, int outside);
static void spin_check(uint64_t now);
static void fire_timers(void);
static uint64_t timers_due;

_Static_assert(offsetof(struct rig_shm, limit_ns) == RIG_SHM_LIMIT_OFFSET, "RIG_SHM_LIMIT_OFFSET is wrong");
_Static_assert(offsetof(struct rig_shm, acks) == RIG_SHM_ACKS_OFFSET, "RIG_SHM_ACKS_OFFSET is wrong");

/* A clock read: the program ran a little, so time moves a quantum (busy loops still advance). Time
   moved by clock reads counts like any other: the read that reaches the run's end asks the session,
   which ends the run there (the request gets no answer), so a loop that only reads the clock cannot
   run past --duration or --sim-timeout. */
static uint64_t now_tick(void)
{
    uint64_t t = __atomic_add_fetch(&shm->sim_ns, shm->quantum_ns, __ATOMIC_SEQ_CST);
    uint64_t limit = __atomic_load_n(&shm->limit_ns, __ATOMIC_RELAXED);
    if (limit && t >= limit)
        wait_until(t, RIG_WAIT_SLEEP);
    if (t >= timers_due)
        fire_timers(); /* (a virtual timer due: its count, or its signal in this thread) */
    spin_check(t);
    return t;
}

/* Asks the session to run the world until wake_ns (or an event); returns why we woke. */
/* The WAIT payload: u64 wake_ns, u32 kind, u32 0. */
struct wait_req {
    uint64_t wake;
    uint32_t kind, zero;
};

/* Moves the shared clock forward to t_ns (never back: another thread may have moved it further). */
static void clock_advance_to(uint64_t t_ns)
{
    uint64_t cur = now_peek();
    while (t_ns > cur && !__atomic_compare_exchange_n(&shm->sim_ns, &cur, t_ns, 0, __ATOMIC_SEQ_CST, __ATOMIC_SEQ_CST))
        ;
}

static uint32_t wait_until(uint64_t wake_ns, uint32_t kind)
{
    struct wait_req req = { wake_ns, kind, 0 };
    uint32_t reason = RIG_WAKE_DEADLINE;
    LOAD(pthread_mutex_lock)(&lock);
    struct rig_hdr h = request(RIG_MSG_WAIT, &req, sizeof req, &reason, sizeof reason);
    clock_advance_to(h.t_ns);
    pthread_mutex_unlock(&lock);
    return reason;
}

/* A sleep: nothing the session does can cut it short, so the outcome is known in advance. The first
   sleep after a request moves the clock itself and tells the session in a notice (RIG_WAIT_AHEAD): no
   round trip, which in a control loop (read sensors, write motors, sleep) is one of two per cycle.
   A second sleep in a row waits for the session as before, so a DUT that only sleeps cannot run ahead
   of it. Whatever the DUT looks at next syncs first (catch_up). */
static void sleep_session(uint64_t wake_ns)
{
    if (now_peek() < wake_ns && !__atomic_load_n(&ahead, __ATOMIC_ACQUIRE)) {
        struct wait_req req = { wake_ns, RIG_WAIT_AHEAD, 0 };
        LOAD(pthread_mutex_lock)(&lock);
        ensure_connected();
        hold_msg(RIG_MSG_WAIT, &req, sizeof req); /* stamped with the time the sleep began */
        clock_advance_to(wake_ns);
        __atomic_store_n(&ahead, 1, __ATOMIC_RELEASE);
        pthread_mutex_unlock(&lock);
        return;
    }
    while (now_peek() < wake_ns)
        wait_until(wake_ns, RIG_WAIT_SLEEP);
}

/* A sleep of this thread: under the rule (threads.c) when it schedules; 1: a virtual timer's signal
   ended it early (EINTR). */
static int sleep_until(uint64_t wake_ns)
{
    if (ruled())
        return rule_wait(wake_ns, NULL, NULL, 0);
    sleep_session(wake_ns);
    return 0;
}

/* Before the DUT looks at anything outside the shim (a pty, a pipe, a file) after a sleep that went
   ahead: a plain WAIT to now, so the session has run the events of that sleep (written their bytes).
   Otherwise what notices are held go now: what the DUT looks at may be answering them. */
static void catch_up(void)
{
    if (__atomic_load_n(&ahead, __ATOMIC_ACQUIRE) && virtual_clock(CLOCK_MONOTONIC))
        wait_until(now_peek(), RIG_WAIT_SLEEP);
    else
        send_held_now();
}

static int valid_ts(const struct timespec *ts)
{
    return ts && ts->tv_sec >= 0 && ts->tv_nsec >= 0 && ts->tv_nsec < (long)NS;
}

EXPORT int clock_gettime(clockid_t id, struct timespec *ts)
{
    if (!virtual_clock(id) || clock_base(id) < 0)
        return LOAD(clock_gettime)(id, ts);
    ns_ts((uint64_t)clock_base(id) + now_tick(), ts);
    return 0;
}

EXPORT int gettimeofday(struct timeval *tv, void *tz)
{
    if (!virtual_clock(CLOCK_REALTIME))
        return LOAD(gettimeofday)(tv, tz);
    uint64_t ns = shm->epoch_ns + now_tick();
    tv->tv_sec = (time_t)(ns / NS);
    tv->tv_usec = (suseconds_t)(ns % NS / 1000);
    return 0;
}

EXPORT time_t time(time_t *out)
{
    if (!virtual_clock(CLOCK_REALTIME))
        return LOAD(time)(out);
    time_t t = (time_t)((shm->epoch_ns + now_tick()) / NS);
    if (out)
        *out = t;
    return t;
}

EXPORT int clock_nanosleep(clockid_t id, int flags, const struct timespec *req, struct timespec *rem)
{
    if (!virtual_clock(id) || clock_base(id) < 0)
        return LOAD(clock_nanosleep)(id, flags, req, rem);
    if (id == CLOCK_THREAD_CPUTIME_ID)
        return EINVAL; /* as Linux */
    if (!valid_ts(req))
        return EINVAL;
    uint64_t wake = flags & TIMER_ABSTIME ? sim_time_on(id, ts_ns(req)) : now_peek() + ts_ns(req);
    if (sleep_until(wake)) {
        if (rem && !(flags & TIMER_ABSTIME))
            ns_ts(wake > now_peek() ? wake - now_peek() : 0, rem);
        return EINTR;
    }
    if (rem && !(flags & TIMER_ABSTIME))
        rem->tv_sec = rem->tv_nsec = 0;
    return 0;
}

EXPORT int nanosleep(const struct timespec *req, struct timespec *rem)
{
    if (!virtual_clock(CLOCK_MONOTONIC))
        return LOAD(nanosleep)(req, rem);
    int err = clock_nanosleep(CLOCK_MONOTONIC, 0, req, rem);
    if (err) {
        errno = err;
        return -1;
    }
    return 0;
}

EXPORT int usleep(useconds_t us)
{
    if (!virtual_clock(CLOCK_MONOTONIC))
        return LOAD(usleep)(us);
    return sleep_until(now_peek() + (uint64_t)us * 1000u) ? errno_ret(EINTR) : 0;
}

EXPORT unsigned int sleep(unsigned int s)
{
    if (!virtual_clock(CLOCK_MONOTONIC))
        return LOAD(sleep)(s);
    uint64_t wake = now_peek() + (uint64_t)s * NS;
    if (sleep_until(wake) && wake > now_peek())
        return (unsigned)((wake - now_peek()) / NS); /* the whole seconds left, as glibc's sleep */
    return 0;
}

/* The waits with timeouts: look (without waiting) for a ready descriptor; if none, let sim time run
   to the deadline or the session's next event (data it writes to a pty), and look again. */
static uint64_t deadline_ms(int timeout_ms)
{
    return timeout_ms < 0 ? RIG_WAIT_FOREVER : now_peek() + (uint64_t)timeout_ms * 1000000u;
}

/* After a look that found nothing ready: 1 when the deadline has passed (the call returns 0), 0 to look
   again once time moved or the session woke it (a pty written), -1 when a virtual timer's signal ended
   the wait (EINTR). Under the rule the thread waits until can_go(arg) says a look would find something. */
static int wait_more(uint64_t deadline, int (*can_go)(void *), void *arg)
{
    if (deadline != RIG_WAIT_FOREVER && now_peek() >= deadline)
        return 1;
    if (ruled())
        return rule_wait(deadline, can_go, arg, 1) ? -1 : 0;
    wait_until(deadline, RIG_WAIT_POLL);
    return 0;
}

/* The result of a poll-family call that found nothing: 0 at its deadline, -1 EINTR. */
static int nothing_ready(int more) { return more > 0 ? 0 : errno_ret(EINTR); }

/* What the rule asks of a thread waiting in poll, select or epoll: would a look find something? */
struct poll_look {
    struct pollfd *fds;
    nfds_t n;
};
static int poll_can_go(void *p)
{
    struct poll_look *l = p;
    return LOAD(poll)(l->fds, l->n, 0) != 0;
}

struct select_look {
    int nfds;
    const fd_set *r, *w, *e; /* the sets asked for (copies are looked at) */
};
static int select_can_go(void *p)
{
    struct select_look *l = p;
    fd_set r, w, e;
    if (l->r)
        r = *l->r;
    if (l->w)
        w = *l->w;
    if (l->e)
        e = *l->e;
    struct timeval zero = { 0, 0 };
    return LOAD(select)(l->nfds, l->r ? &r : NULL, l->w ? &w : NULL, l->e ? &e : NULL, &zero) != 0;
}

static int epoll_can_go(void *epfd)
{
    struct pollfd p = { .fd = (int)(intptr_t)epfd, .events = POLLIN };
    return LOAD(poll)(&p, 1, 0) != 0;
}

EXPORT int poll(struct pollfd *fds, nfds_t n, int timeout)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || timeout == 0)
        return LOAD(poll)(fds, n, timeout);
    uint64_t deadline = deadline_ms(timeout);
    struct poll_look look = { fds, n };
    for (;;) {
        int r = LOAD(poll)(fds, n, 0);
        if (r != 0)
            return r;
        int more = wait_more(deadline, poll_can_go, &look);
        if (more)
            return nothing_ready(more);
    }
}

EXPORT int __poll_chk(struct pollfd *fds, nfds_t n, int timeout, size_t fdslen)
{
    (void)fdslen;
    return poll(fds, n, timeout);
}

EXPORT int ppoll(struct pollfd *fds, nfds_t n, const struct timespec *tmo, const sigset_t *mask)
{
    static const struct timespec zero = { 0, 0 };
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || (tmo && tmo->tv_sec == 0 && tmo->tv_nsec == 0))
        return LOAD(ppoll)(fds, n, tmo, mask);
    if (tmo && !valid_ts(tmo)) {
        errno = EINVAL;
        return -1;
    }
    uint64_t deadline = tmo ? now_peek() + ts_ns(tmo) : RIG_WAIT_FOREVER;
    struct poll_look look = { fds, n };
    for (;;) {
        int r = LOAD(ppoll)(fds, n, &zero, mask);
        if (r != 0)
            return r;
        int more = wait_more(deadline, poll_can_go, &look);
        if (more)
            return nothing_ready(more);
    }
}

static int select_virtual(int nfds, fd_set *r, fd_set *w, fd_set *e, uint64_t deadline, const sigset_t *mask,
                          int use_pselect)
{
    fd_set r0, w0, e0;
    if (r)
        r0 = *r;
    if (w)
        w0 = *w;
    if (e)
        e0 = *e;
    struct select_look look = { nfds, r ? &r0 : NULL, w ? &w0 : NULL, e ? &e0 : NULL };
    for (;;) {
        if (r)
            *r = r0;
        if (w)
            *w = w0;
        if (e)
            *e = e0;
        int res;
        if (use_pselect) {
            struct timespec zero = { 0, 0 };
            res = LOAD(pselect)(nfds, r, w, e, &zero, mask);
        } else {
            struct timeval zero = { 0, 0 };
            res = LOAD(select)(nfds, r, w, e, &zero);
        }
        if (res != 0)
            return res;
        int more = wait_more(deadline, select_can_go, &look);
        if (more) {
            if (r) /* (nothing ready: every set comes back empty) */
                FD_ZERO(r);
            if (w)
                FD_ZERO(w);
            if (e)
                FD_ZERO(e);
            return nothing_ready(more);
        }
    }
}

EXPORT int select(int nfds, fd_set *r, fd_set *w, fd_set *e, struct timeval *tmo)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || (tmo && tmo->tv_sec == 0 && tmo->tv_usec == 0))
        return LOAD(select)(nfds, r, w, e, tmo);
    if (tmo && (tmo->tv_sec < 0 || tmo->tv_usec < 0)) {
        errno = EINVAL;
        return -1;
    }
    uint64_t deadline =
        tmo ? now_peek() + (uint64_t)tmo->tv_sec * NS + (uint64_t)tmo->tv_usec * 1000u : RIG_WAIT_FOREVER;
    int res = select_virtual(nfds, r, w, e, deadline, NULL, 0);
    if (tmo && res >= 0)
        tmo->tv_sec = tmo->tv_usec = 0; /* Linux reports the time left; a woken select is close enough to 0 */
    return res;
}

EXPORT int pselect(int nfds, fd_set *r, fd_set *w, fd_set *e, const struct timespec *tmo, const sigset_t *mask)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || (tmo && tmo->tv_sec == 0 && tmo->tv_nsec == 0))
        return LOAD(pselect)(nfds, r, w, e, tmo, mask);
    if (tmo && !valid_ts(tmo)) {
        errno = EINVAL;
        return -1;
    }
    return select_virtual(nfds, r, w, e, tmo ? now_peek() + ts_ns(tmo) : RIG_WAIT_FOREVER, mask, 1);
}

EXPORT int epoll_wait(int epfd, struct epoll_event *ev, int max, int timeout)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || timeout == 0)
        return LOAD(epoll_wait)(epfd, ev, max, timeout);
    uint64_t deadline = deadline_ms(timeout);
    for (;;) {
        int r = LOAD(epoll_wait)(epfd, ev, max, 0);
        if (r != 0)
            return r;
        int more = wait_more(deadline, epoll_can_go, (void *)(intptr_t)epfd);
        if (more)
            return nothing_ready(more);
    }
}

EXPORT int epoll_pwait(int epfd, struct epoll_event *ev, int max, int timeout, const sigset_t *mask)
{
    catch_up();
    if (!virtual_clock(CLOCK_MONOTONIC) || timeout == 0)
        return LOAD(epoll_pwait)(epfd, ev, max, timeout, mask);
    uint64_t deadline = deadline_ms(timeout);
    for (;;) {
        int r = LOAD(epoll_pwait)(epfd, ev, max, 0, mask);
        if (r != 0)
            return r;
        int more = wait_more(deadline, epoll_can_go, (void *)(intptr_t)epfd);
        if (more)
            return nothing_ready(more);
    }
}
