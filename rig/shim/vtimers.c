/*
 * Virtual timers (lockstep): timerfd_create/settime/gettime and read, and alarm/setitimer/getitimer's
 * ITIMER_REAL, on the session's clock. A timerfd is an eventfd: it counts expirations as a timerfd
 * does (a read takes the count, 8 bytes, and zeroes it; EAGAIN or a wait while it is 0), and the
 * kernel makes it readable for poll, select and epoll, so those need nothing of their own. The shim
 * adds the expirations due when the clock passes them: at a clock read (vtime.c now_tick) and whenever
 * the rule (threads.c) looks who can go on; time moves to the earliest expiry when every thread
 * waits. ITIMER_REAL's SIGALRM goes to the thread that runs when it is due (at a clock read or a wait),
 * whose wait then ends with EINTR, as a signal handler ends one. Part of rigshim.c (one translation
 * unit): see its top comment.
 */

#define MAX_TIMERS 64

struct vtimer {
    int fd;            /* the timerfd (an eventfd); -1: ITIMER_REAL's; 0 with next 0: unused slot */
    clockid_t clock;   /* the clock its absolute times are on */
    uint64_t next;     /* sim time of the next expiry (0: disarmed) */
    uint64_t interval; /* ns between expiries (0: once) */
    int used;
};
static struct vtimer vtimers[MAX_TIMERS]; /* [0]: ITIMER_REAL */
static int n_armed;
static int timers_made;                        /* a timerfd was made: descriptors are looked up (vtimer_of) */
static uint64_t timers_due = RIG_WAIT_FOREVER; /* the earliest next of an armed timer (vtime.c reads it) */

static int timers_armed(void) { return n_armed > 0; }
static void interrupted_here(void);

static uint64_t timers_next(void) { return timers_due; }

static void timers_recount(void)
{
    n_armed = 0;
    timers_due = RIG_WAIT_FOREVER;
    for (int i = 0; i < MAX_TIMERS; i++)
        if (vtimers[i].used && vtimers[i].next) {
            n_armed++;
            if (vtimers[i].next < timers_due)
                timers_due = vtimers[i].next;
        }
}

static struct vtimer *vtimer_of(int fd)
{
    if (fd < 0 || !timers_made)
        return NULL;
    for (int i = 1; i < MAX_TIMERS; i++)
        if (vtimers[i].used && vtimers[i].fd == fd)
            return &vtimers[i];
    return NULL;
}

/* Expirations due at now: counted into the timerfds, SIGALRM raised in this thread. */
static void fire_timers(void)
{
    uint64_t now = now_peek();
    if (now < timers_due)
        return;
    for (int i = 0; i < MAX_TIMERS; i++) {
        struct vtimer *t = &vtimers[i];
        if (!t->used || !t->next || t->next > now)
            continue;
        uint64_t n = 1 + (t->interval ? (now - t->next) / t->interval : 0);
        t->next = t->interval ? t->next + n * t->interval : 0;
        if (t->fd >= 0) {
            LOAD(write)(t->fd, &n, sizeof n);
        } else {
            interrupted_here();
            syscall(SYS_tgkill, self_pid(), gettid(), SIGALRM);
        }
    }
    timers_recount();
}

/* ---------------------------------------------------------------- timerfd */

static int virtual_timer_clock(clockid_t c)
{
    return c == CLOCK_REALTIME || c == CLOCK_MONOTONIC || c == CLOCK_BOOTTIME || c == CLOCK_REALTIME_ALARM ||
           c == CLOCK_BOOTTIME_ALARM;
}

EXPORT int timerfd_create(clockid_t clock, int flags)
{
    if (!virtual_clock(clock))
        return LOAD(timerfd_create)(clock, flags);
    if (!virtual_timer_clock(clock) || (flags & ~(TFD_NONBLOCK | TFD_CLOEXEC)))
        return errno_ret(EINVAL);
    int slot = 1;
    while (slot < MAX_TIMERS && vtimers[slot].used)
        slot++;
    if (slot == MAX_TIMERS)
        return errno_ret(EMFILE);
    int fd = eventfd(0, (flags & TFD_NONBLOCK ? EFD_NONBLOCK : 0) | (flags & TFD_CLOEXEC ? EFD_CLOEXEC : 0));
    if (fd < 0)
        return -1;
    vtimers[slot] = (struct vtimer){ .fd = fd, .clock = clock, .used = 1 };
    timers_made = 1;
    return fd;
}

static void to_itimerspec(const struct vtimer *t, struct itimerspec *out)
{
    uint64_t now = now_peek();
    ns_ts(t->next > now ? t->next - now : 0, &out->it_value);
    if (t->next && t->next <= now)
        out->it_value.tv_nsec = 1; /* due and not yet counted: the kernel shows the least time */
    ns_ts(t->interval, &out->it_interval);
}

/* Arms t (value 0: disarms) as timerfd_settime and setitimer do; the count taken so far is zeroed. */
static int arm(struct vtimer *t, int absolute, const struct timespec *value, const struct timespec *interval)
{
    if (!valid_ts(value) || !valid_ts(interval))
        return EINVAL;
    uint64_t v = ts_ns(value);
    if (t->fd >= 0) {
        uint64_t drop;
        while (LOAD(poll)(&(struct pollfd){ .fd = t->fd, .events = POLLIN }, 1, 0) == 1 &&
               LOAD(read)(t->fd, &drop, sizeof drop) == sizeof drop)
            ;
    }
    if (v == 0)
        t->next = 0;
    else if (absolute)
        t->next = sim_time_on(t->clock, v) ? sim_time_on(t->clock, v) : 1; /* (0 means disarmed) */
    else
        t->next = now_peek() + v;
    t->interval = t->next ? ts_ns(interval) : 0;
    timers_recount();
    fire_timers(); /* (an absolute time already past counts at once) */
    return 0;
}

EXPORT int timerfd_settime(int fd, int flags, const struct itimerspec *value, struct itimerspec *old)
{
    struct vtimer *t = vtimer_of(fd);
    if (!t)
        return LOAD(timerfd_settime)(fd, flags, value, old);
    if (!value || (flags & ~(TFD_TIMER_ABSTIME | TFD_TIMER_CANCEL_ON_SET)))
        return errno_ret(value ? EINVAL : EFAULT);
    if (old)
        to_itimerspec(t, old);
    int err = arm(t, flags & TFD_TIMER_ABSTIME, &value->it_value, &value->it_interval);
    return err ? errno_ret(err) : 0;
}

EXPORT int timerfd_gettime(int fd, struct itimerspec *cur)
{
    struct vtimer *t = vtimer_of(fd);
    if (!t)
        return LOAD(timerfd_gettime)(fd, cur);
    fire_timers();
    to_itimerspec(t, cur);
    return 0;
}

static int timer_counted(void *fd)
{
    return LOAD(poll)(&(struct pollfd){ .fd = (int)(intptr_t)fd, .events = POLLIN }, 1, 0) == 1;
}

/* read on a timerfd: 8 bytes at least (EINVAL), the count when there is one; else EAGAIN (O_NONBLOCK)
   or a wait under the rule until the next expiry counts. */
static ssize_t timer_read(struct vtimer *t, void *buf, size_t n)
{
    if (n < sizeof(uint64_t))
        return errno_ret(EINVAL);
    fire_timers();
    int nonblocking = LOAD(fcntl)(t->fd, F_GETFL) & O_NONBLOCK;
    while (!nonblocking && !timer_counted((void *)(intptr_t)t->fd)) {
        if (!ruled()) {
            if (!t->next)
                break; /* (disarmed: the real read blocks, as the kernel's would, forever) */
            sleep_until(t->next);
            fire_timers();
        } else if (rule_wait(RIG_WAIT_FOREVER, timer_counted, (void *)(intptr_t)t->fd, 0)) {
            return errno_ret(EINTR);
        }
    }
    return LOAD(read)(t->fd, buf, n);
}

static void timer_closed(int fd)
{
    struct vtimer *t = vtimer_of(fd);
    if (t) {
        *t = (struct vtimer){ 0 };
        timers_recount();
    }
}

/* ---------------------------------------------------------------- alarm, setitimer, getitimer */

static int virtual_itimer(int which) { return which == ITIMER_REAL && virtual_clock(CLOCK_MONOTONIC); }

EXPORT int setitimer(__itimer_which_t which, const struct itimerval *value, struct itimerval *old)
{
    if (!virtual_itimer(which))
        return LOAD(setitimer)(which, value, old);
    struct vtimer *t = &vtimers[0];
    t->used = 1;
    t->fd = -1;
    t->clock = CLOCK_MONOTONIC;
    if (old) {
        struct itimerspec cur;
        to_itimerspec(t, &cur);
        old->it_value = (struct timeval){ cur.it_value.tv_sec, (cur.it_value.tv_nsec + 999) / 1000 };
        old->it_interval = (struct timeval){ cur.it_interval.tv_sec, cur.it_interval.tv_nsec / 1000 };
    }
    if (!value)
        return 0;
    if (value->it_value.tv_usec < 0 || value->it_value.tv_usec >= 1000000 || value->it_interval.tv_usec < 0 ||
        value->it_interval.tv_usec >= 1000000)
        return errno_ret(EINVAL);
    struct timespec v = { value->it_value.tv_sec, value->it_value.tv_usec * 1000 };
    struct timespec i = { value->it_interval.tv_sec, value->it_interval.tv_usec * 1000 };
    int err = arm(t, 0, &v, &i);
    return err ? errno_ret(err) : 0;
}

EXPORT int getitimer(__itimer_which_t which, struct itimerval *cur)
{
    if (!virtual_itimer(which))
        return LOAD(getitimer)(which, cur);
    struct itimerval none = { 0 };
    return setitimer(which, NULL, cur ? cur : &none);
}

EXPORT unsigned int alarm(unsigned int seconds)
{
    if (!virtual_itimer(ITIMER_REAL))
        return LOAD(alarm)(seconds);
    struct itimerval value = { .it_value = { seconds, 0 } }, old;
    setitimer(ITIMER_REAL, &value, &old);
    return (unsigned)old.it_value.tv_sec +
           (old.it_value.tv_usec >= 500000 || (!old.it_value.tv_sec && old.it_value.tv_usec));
}

/* pause under the rule (a virtual timer armed, or several threads): until a virtual timer's signal runs
   its handler in this thread (EINTR, as always). Otherwise the kernel's. */
EXPORT int pause(void)
{
    if (!ruled())
        return LOAD(pause)();
    while (!rule_wait(RIG_WAIT_FOREVER, NULL, NULL, 0))
        ;
    return errno_ret(EINTR);
}
