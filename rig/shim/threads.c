/*
 * The DUT's threads in one virtual time (lockstep). At most one DUT thread runs at a time: it holds
 * the baton. A thread gives it up only in a wait the shim knows (a sleep, the poll family, a timerfd's
 * read, a condition variable, a semaphore, a contended mutex or read-write lock, a barrier,
 * pthread_join, sched_yield) or when it
 * ends; the rule then picks the next: among the threads that can go on (a deadline reached, a
 * descriptor ready, signalled, the mutex free), the earliest key first, ties by creation order. A
 * thread's key is its deadline when that woke it, else the time it was seen able to go on; a thread
 * that yields or is new counts from now. Only when none can go on does time move, to the earliest
 * deadline of all (threads and timers, vtimers.c): one WAIT to the session for the whole process, so the
 * session sees one waiter as before. A thread that computes holds the clock: time moves only by its
 * clock reads. Everything depends on virtual time and the program's own actions, never on the host's
 * scheduler: the same seed gives the same bytes. A thread that runs on past SPIN_LIMIT_NS of virtual
 * time while another was due is a spinning thread: the run ends naming it (RIG_MSG_STALL).
 *
 * Barriers are kept here too (the end of this file).
 *
 * The rule only engages once it is needed: a process with one thread and no virtual timer keeps the
 * single-threaded paths of vtime.c (the sleep that goes ahead, one round trip per wait), so the
 * reference FC runs as fast as before. Part of rigshim.c (one translation unit): see its top comment.
 */

#define MAX_THREADS 128
#define SPIN_LIMIT_NS 1000000000ull /* a second of virtual time computing while another is due */

enum { T_FREE, T_RUNNING, T_READY, T_WAITING, T_EXITED };

struct vthread {
    int state;
    uint32_t go;              /* futex word: 1 while this thread holds the baton */
    uint64_t deadline;        /* waiting: wakes then (RIG_WAIT_FOREVER: no deadline) */
    uint64_t key;             /* ready: its place in the rule */
    int (*can_go)(void *arg); /* waiting: whether it can go on before its deadline (NULL: it cannot) */
    void *arg;
    int outside;     /* waiting on descriptors: the session's writes (a pty) may end the wait */
    int interrupted; /* a virtual timer's signal ran its handler in this thread during the wait */
    pid_t tid;
    pthread_t self;
    uint64_t born; /* creation order: 1 for the thread that ran main, then each pthread_create */
};

static struct vthread vthreads[MAX_THREADS];
static int n_vthreads;           /* slots used (0: the thread that ran main; an ended thread's is reused) */
static uint64_t births;          /* threads the rule has known */
static int threaded;             /* lockstep and a second DUT thread made: the rule schedules */
static int baton = -1;           /* the slot that runs */
static uint64_t spin_after = -1; /* (RIG_WAIT_FOREVER) a clock read past this catches a spinner */
static int spin_told;
static __thread int my_slot; /* this thread's slot + 1 (0: a thread the shim never saw start) */

static int me(void) { return my_slot - 1; }

/* Sleeps until the baton is this slot's (a futex of this process's only, no timeout). */
static void await_baton(int slot)
{
    while (!__atomic_load_n(&vthreads[slot].go, __ATOMIC_SEQ_CST))
        syscall(SYS_futex, &vthreads[slot].go, FUTEX_WAIT_PRIVATE, 0, NULL, NULL, 0);
}

static void pass_baton(int slot)
{
    __atomic_store_n(&baton, slot, __ATOMIC_SEQ_CST);
    __atomic_store_n(&vthreads[slot].go, 1, __ATOMIC_SEQ_CST);
    syscall(SYS_futex, &vthreads[slot].go, FUTEX_WAKE_PRIVATE, 1, NULL, NULL, 0);
}

/* Whether a thread other than the caller may still run (ready or waiting). */
static int others_alive(int self)
{
    for (int i = 0; i < n_vthreads; i++)
        if (i != self && (vthreads[i].state == T_READY || vthreads[i].state == T_WAITING))
            return 1;
    return 0;
}

/* Whether this thread's waits go through the rule: lockstep, a thread the shim knows, and the rule
   needed (several threads, or a virtual timer to fire). */
static int ruled(void) { return lockstep && active && my_slot > 0 && (threaded || timers_armed()); }

static void thread_name(int slot, char *buf, size_t n)
{
    char path[64];
    snprintf(path, sizeof path, "/proc/self/task/%d/comm", (int)vthreads[slot].tid);
    int fd = LOAD(open)(path, O_RDONLY | O_CLOEXEC);
    ssize_t k = fd >= 0 ? LOAD(read)(fd, buf, n - 1) : -1;
    if (fd >= 0)
        LOAD(close)(fd);
    buf[k > 0 ? k - (buf[k - 1] == '\n') : 0] = 0;
}

/* A thread that runs on while another is due: the run ends, naming both (the session's watchdog). */
static void spin_caught(uint64_t now)
{
    if (spin_told)
        return;
    spin_told = 1;
    int due = -1;
    for (int i = 0; i < n_vthreads; i++)
        if (i != baton && (vthreads[i].state == T_READY || vthreads[i].state == T_WAITING) &&
            (due < 0 || (vthreads[i].state == T_READY ? vthreads[i].key : vthreads[i].deadline) <
                            (vthreads[due].state == T_READY ? vthreads[due].key : vthreads[due].deadline)))
            due = i;
    char spinner[17] = "?", other[17] = "?", text[256];
    thread_name(baton, spinner, sizeof spinner);
    if (due >= 0)
        thread_name(due, other, sizeof other);
    int n = snprintf(text, sizeof text,
                     "thread '%s' (number %d in the order the shim saw threads start) spins: it ran on for %.3f s of "
                     "virtual time without a wait the shim knows while thread '%s' was due",
                     spinner, (int)vthreads[baton].born, (double)(now - (spin_after - SPIN_LIMIT_NS)) / 1e9, other);
    pthread_mutex_lock(&lock);
    ensure_connected();
    send_msg(RIG_MSG_STALL, text, (uint32_t)n);
    pthread_mutex_unlock(&lock);
}

/* A clock read by the thread that runs (vtime.c now_tick): the spinner's check, no message. */
static void spin_check(uint64_t now)
{
    if (threaded && now > spin_after)
        spin_caught(now);
}

/* The earliest a thread other than the runner was due (ready: its key; waiting: its deadline). */
static void spin_arm(void)
{
    uint64_t due = RIG_WAIT_FOREVER;
    for (int i = 0; i < n_vthreads; i++) {
        const struct vthread *t = &vthreads[i];
        uint64_t at = t->state == T_READY ? t->key : t->state == T_WAITING ? t->deadline : RIG_WAIT_FOREVER;
        if (i != baton && at < due)
            due = at;
    }
    spin_after = due == RIG_WAIT_FOREVER ? RIG_WAIT_FOREVER : due + SPIN_LIMIT_NS;
}

/* Which waiting threads can go on now (deadline reached, or their condition), then the rule: the
   ready thread with the smallest key, ties by creation order; -1 when none can go on. */
static int pick(uint64_t now)
{
    int best = -1;
    for (int i = 0; i < n_vthreads; i++) {
        struct vthread *t = &vthreads[i];
        if (t->state == T_WAITING) {
            if (t->interrupted) {
                t->state = T_READY;
                t->key = now;
            } else if (t->deadline <= now) {
                t->state = T_READY;
                t->key = t->deadline;
            } else if (t->can_go && t->can_go(t->arg)) {
                t->state = T_READY;
                t->key = now;
            }
        }
        if (t->state == T_READY && (best < 0 || t->key < vthreads[best].key ||
                                    (t->key == vthreads[best].key && t->born < vthreads[best].born)))
            best = i;
    }
    return best;
}

/* Time moves (nobody can go on): to the earliest deadline of a thread or a timer, through the session
   as a sleep, or as a poll's wait when a thread waits on descriptors the session may make ready. */
static void advance(void)
{
    uint64_t to = timers_next();
    int outside = 0;
    for (int i = 0; i < n_vthreads; i++)
        if (vthreads[i].state == T_WAITING) {
            if (vthreads[i].deadline < to)
                to = vthreads[i].deadline;
            outside |= vthreads[i].outside;
        }
    if (outside || to == RIG_WAIT_FOREVER)
        wait_until(to, RIG_WAIT_POLL); /* (forever: a slice at a time; a deadlock ends at the sim timeout) */
    else
        sleep_session(to);
}

/* Hands the baton from this thread (its state set: waiting, ready or exited) to the rule's choice, and
   returns when this thread holds it again (never, for a thread that ended). */
static void reschedule(void)
{
    int self = me();
    const int ending = vthreads[self].state == T_EXITED; /* (its slot may be a new thread's once passed on) */
    for (;;) {
        if (ending && !others_alive(self))
            return; /* (the process ends with this thread) */
        fire_timers();
        int next = pick(now_peek());
        if (next < 0) {
            advance();
            continue;
        }
        vthreads[next].state = T_RUNNING;
        if (next == self)
            break;
        __atomic_store_n(&vthreads[self].go, 0, __ATOMIC_SEQ_CST);
        pass_baton(next);
        if (ending)
            return;
        await_baton(self);
        break;
    }
    baton = self;
    spin_arm();
}

/* This thread waits until deadline or can_go(arg); 1 if a virtual timer's signal interrupted it. */
static int rule_wait(uint64_t deadline, int (*can_go)(void *), void *arg, int outside)
{
    struct vthread *t = &vthreads[me()];
    t->state = T_WAITING;
    t->deadline = deadline;
    t->can_go = can_go;
    t->arg = arg;
    t->outside = outside;
    t->interrupted = 0;
    reschedule();
    t->can_go = NULL;
    int interrupted = t->interrupted;
    t->interrupted = 0;
    return interrupted;
}

/* A virtual timer's signal runs its handler in this thread now (vtimers.c): a wait it is in ends. */
static void interrupted_here(void)
{
    if (my_slot > 0 && vthreads[me()].state == T_WAITING)
        vthreads[me()].interrupted = 1;
}

/* ---------------------------------------------------------------- thread lifetimes */

/* The first thread the rule knows is the one that ran main (the constructor's). */
static void threads_init(void)
{
    n_vthreads = 1;
    births = 1;
    vthreads[0] = (struct vthread){ .state = T_RUNNING, .go = 1, .tid = gettid(), .self = pthread_self(), .born = 1 };
    baton = 0;
    my_slot = 1;
}

/* A fork's child has one thread, the forking one: it starts the rule afresh. */
static void threads_after_fork(void)
{
    if (!my_slot)
        return;
    threaded = 0;
    spin_after = RIG_WAIT_FOREVER;
    spin_told = 0;
    threads_init();
}

struct start {
    void *(*fn)(void *);
    void *arg;
    int slot;
};

static void thread_ends(void)
{
    if (my_slot <= 0 || !threaded)
        return;
    vthreads[me()].state = T_EXITED;
    reschedule();
    my_slot = 0;
}

/* A new thread waits for the baton before it runs a line of the program's. */
static void *thread_start(void *p)
{
    struct start s = *(struct start *)p;
    free(p);
    my_slot = s.slot + 1;
    vthreads[s.slot].tid = gettid();
    await_baton(s.slot);
    baton = s.slot;
    spin_arm();
    void *r = s.fn(s.arg);
    thread_ends();
    return r;
}

EXPORT int pthread_create(pthread_t *thread, const pthread_attr_t *attr, void *(*start)(void *), void *arg)
{
    pthread_attr_t copy;
    if (lockstep_attr(attr, &copy))
        attr = &copy;
    int slot = 0; /* an ended thread's slot, else a new one */
    while (slot < n_vthreads && vthreads[slot].state != T_EXITED && vthreads[slot].state != T_FREE)
        slot++;
    if (!lockstep || !active || my_slot <= 0 || slot >= MAX_THREADS)
        return LOAD(pthread_create)(thread, attr, start, arg);
    struct start *s = malloc(sizeof *s);
    if (!s)
        return EAGAIN;
    *s = (struct start){ start, arg, slot };
    /* ready from now, after every thread already ready (the rule: key, then creation order) */
    vthreads[slot] = (struct vthread){ .state = T_READY, .key = now_peek(), .born = births + 1 };
    int err = LOAD(pthread_create)(thread, attr, thread_start, s);
    if (err) {
        vthreads[slot].state = T_FREE;
        free(s);
        return err;
    }
    vthreads[slot].self = *thread;
    births++;
    if (slot == n_vthreads)
        n_vthreads++;
    threaded = 1;
    spin_arm();
    return 0;
}

EXPORT void pthread_exit(void *r)
{
    thread_ends();
    LOAD(pthread_exit)(r);
    __builtin_unreachable();
}

/* The slot of thread t: the youngest with its id (glibc gives a joined thread's id to a new thread). */
static int slot_of(pthread_t t)
{
    int found = -1;
    for (int i = 0; i < n_vthreads; i++)
        if (pthread_equal(vthreads[i].self, t) && (found < 0 || vthreads[i].born > vthreads[found].born))
            found = i;
    return found;
}

static int has_ended(void *slot) { return vthreads[(intptr_t)slot].state == T_EXITED; }

EXPORT int pthread_join(pthread_t t, void **r)
{
    if (ruled()) {
        int slot = slot_of(t);
        if (slot >= 0 && vthreads[slot].state != T_EXITED)
            rule_wait(RIG_WAIT_FOREVER, has_ended, (void *)(intptr_t)slot, 0);
    }
    return LOAD(pthread_join)(t, r);
}

EXPORT int sched_yield(void)
{
    if (!ruled() || !threaded)
        return LOAD(sched_yield)();
    struct vthread *t = &vthreads[me()];
    t->state = T_READY;
    t->key = now_peek();
    reschedule();
    return 0;
}

/* ---------------------------------------------------------------- mutexes, condition variables, semaphores */

/* A mutex another thread holds: wait (the holder runs until it waits or unlocks) until it looks free,
   then take it. glibc's lock word is 0 when nobody holds it. */
static int mutex_free(void *m) { return ((pthread_mutex_t *)m)->__data.__lock == 0; }

static int mutex_wait(pthread_mutex_t *m, uint64_t deadline)
{
    for (;;) {
        int err = LOAD(pthread_mutex_trylock)(m);
        if (err != EBUSY)
            return err;
        if (m->__data.__owner == gettid())
            return EDEADLK; /* (an error-checking mutex this thread holds) */
        if (now_peek() >= deadline)
            return ETIMEDOUT;
        rule_wait(deadline, mutex_free, m, 0);
    }
}

EXPORT int pthread_mutex_lock(pthread_mutex_t *m)
{
    if (!threaded || my_slot <= 0 || !lockstep)
        return LOAD(pthread_mutex_lock)(m);
    int err = mutex_wait(m, RIG_WAIT_FOREVER);
    if (err == EDEADLK && (m->__data.__kind & 3) != PTHREAD_MUTEX_ERRORCHECK)
        return LOAD(pthread_mutex_lock)(m); /* (a normal mutex locked twice deadlocks, as without the rig) */
    return err;
}

/* A deadline on a clock, as a sim time (0 for one already past). */
static uint64_t sim_deadline(clockid_t clock, const struct timespec *abs) { return sim_time_on(clock, ts_ns(abs)); }

EXPORT int pthread_mutex_timedlock(pthread_mutex_t *m, const struct timespec *abs)
{
    if (!threaded || my_slot <= 0 || !lockstep)
        return LOAD(pthread_mutex_timedlock)(m, abs);
    if (!valid_ts(abs))
        return EINVAL;
    return mutex_wait(m, sim_deadline(CLOCK_REALTIME, abs));
}

/* A read-write lock another thread holds: wait until a try would take it (the rule's look takes it and
   gives it back at once, so the lock's owner is always the thread that holds it), then take it. */
struct rwlock_look {
    pthread_rwlock_t *l;
    int write;
};

static int rwlock_try(pthread_rwlock_t *l, int write)
{
    return write ? LOAD(pthread_rwlock_trywrlock)(l) : LOAD(pthread_rwlock_tryrdlock)(l);
}

static int rwlock_free(void *p)
{
    struct rwlock_look *look = p;
    if (rwlock_try(look->l, look->write))
        return 0;
    LOAD(pthread_rwlock_unlock)(look->l);
    return 1;
}

static int rwlock_wait(pthread_rwlock_t *l, int write, uint64_t deadline)
{
    struct rwlock_look look = { l, write };
    for (;;) {
        int err = rwlock_try(l, write);
        if (err != EBUSY)
            return err;
        if (now_peek() >= deadline)
            return ETIMEDOUT;
        rule_wait(deadline, rwlock_free, &look, 0);
    }
}

/* The read-write locks are the rule's once several threads run (else glibc's). */
#define RWLOCK_CALLS(name, write)                                                                                 \
    EXPORT int pthread_rwlock_##name##lock(pthread_rwlock_t *l)                                                   \
    {                                                                                                             \
        if (!threaded || my_slot <= 0 || !lockstep)                                                               \
            return LOAD(pthread_rwlock_##name##lock)(l);                                                          \
        return rwlock_wait(l, write, RIG_WAIT_FOREVER);                                                           \
    }                                                                                                             \
    EXPORT int pthread_rwlock_timed##name##lock(pthread_rwlock_t *l, const struct timespec *abs)                  \
    {                                                                                                             \
        if (!threaded || my_slot <= 0 || !lockstep)                                                               \
            return LOAD(pthread_rwlock_timed##name##lock)(l, abs);                                                \
        return valid_ts(abs) ? rwlock_wait(l, write, sim_deadline(CLOCK_REALTIME, abs)) : EINVAL;                 \
    }                                                                                                             \
    EXPORT int pthread_rwlock_clock##name##lock(pthread_rwlock_t *l, clockid_t clock, const struct timespec *abs) \
    {                                                                                                             \
        if (!threaded || my_slot <= 0 || !lockstep)                                                               \
            return LOAD(pthread_rwlock_clock##name##lock)(l, clock, abs);                                         \
        if (!valid_ts(abs) || (clock != CLOCK_REALTIME && clock != CLOCK_MONOTONIC))                              \
            return EINVAL;                                                                                        \
        return rwlock_wait(l, write, sim_deadline(clock, abs));                                                   \
    }
RWLOCK_CALLS(rd, 0)
RWLOCK_CALLS(wr, 1)

/* A condition variable: the waiters the rule knows, in the order they began to wait; a signal makes
   the first signalled (it goes on when the rule picks it), a broadcast all. */
struct cond_wait {
    pthread_cond_t *cond;
    uint64_t seq;
    int signalled;
};
static struct cond_wait *cond_waits[MAX_THREADS];
static uint64_t cond_seq;

static int signalled(void *w) { return ((struct cond_wait *)w)->signalled; }

static int cond_wait_virtual(pthread_cond_t *c, pthread_mutex_t *m, uint64_t deadline)
{
    struct cond_wait w = { c, cond_seq++, 0 };
    cond_waits[me()] = &w;
    LOAD(pthread_mutex_unlock)(m);
    rule_wait(deadline, signalled, &w, 0);
    cond_waits[me()] = NULL;
    int err = threaded ? mutex_wait(m, RIG_WAIT_FOREVER) : LOAD(pthread_mutex_lock)(m);
    return err ? err : w.signalled ? 0 : ETIMEDOUT;
}

static void cond_wake(pthread_cond_t *c, int all)
{
    for (;;) {
        struct cond_wait *first = NULL;
        for (int i = 0; i < n_vthreads; i++) {
            struct cond_wait *w = cond_waits[i];
            if (w && w->cond == c && !w->signalled && (!first || w->seq < first->seq))
                first = w;
        }
        if (!first)
            return;
        first->signalled = 1;
        if (!all)
            return;
    }
}

/* glibc keeps the clock of a condition variable in __wrefs (bit 1: CLOCK_MONOTONIC). */
static clockid_t cond_clock(const pthread_cond_t *c)
{
    return (c->__data.__wrefs & 2) ? CLOCK_MONOTONIC : CLOCK_REALTIME;
}

static int cond_ruled(void) { return lockstep && active && my_slot > 0; }

EXPORT int pthread_cond_wait(pthread_cond_t *c, pthread_mutex_t *m)
{
    if (!cond_ruled())
        return LOAD(pthread_cond_wait)(c, m);
    return cond_wait_virtual(c, m, RIG_WAIT_FOREVER);
}

EXPORT int pthread_cond_timedwait(pthread_cond_t *c, pthread_mutex_t *m, const struct timespec *abs)
{
    if (!cond_ruled())
        return LOAD(pthread_cond_timedwait)(c, m, abs);
    if (!valid_ts(abs))
        return EINVAL;
    return cond_wait_virtual(c, m, sim_deadline(cond_clock(c), abs));
}

EXPORT int pthread_cond_clockwait(pthread_cond_t *c, pthread_mutex_t *m, clockid_t clock, const struct timespec *abs)
{
    if (!cond_ruled())
        return LOAD(pthread_cond_clockwait)(c, m, clock, abs);
    if (!valid_ts(abs) || (clock != CLOCK_REALTIME && clock != CLOCK_MONOTONIC))
        return EINVAL;
    return cond_wait_virtual(c, m, sim_deadline(clock, abs));
}

EXPORT int pthread_cond_signal(pthread_cond_t *c)
{
    if (cond_ruled())
        cond_wake(c, 0);
    return LOAD(pthread_cond_signal)(c);
}

EXPORT int pthread_cond_broadcast(pthread_cond_t *c)
{
    if (cond_ruled())
        cond_wake(c, 1);
    return LOAD(pthread_cond_broadcast)(c);
}

static int sem_positive(void *s)
{
    int v = 0;
    sem_getvalue((sem_t *)s, &v);
    return v > 0;
}

/* sem_wait and its deadlines: take it if it is up, else wait under the rule until it is (another
   thread's sem_post) or the deadline passes. */
static int sem_wait_virtual(sem_t *s, uint64_t deadline)
{
    for (;;) {
        if (LOAD(sem_trywait)(s) == 0)
            return 0;
        if (errno != EAGAIN)
            return -1;
        if (now_peek() >= deadline)
            return errno_ret(ETIMEDOUT);
        if (rule_wait(deadline, sem_positive, s, 0))
            return errno_ret(EINTR);
    }
}

EXPORT int sem_wait(sem_t *s) { return cond_ruled() ? sem_wait_virtual(s, RIG_WAIT_FOREVER) : LOAD(sem_wait)(s); }

EXPORT int sem_timedwait(sem_t *s, const struct timespec *abs)
{
    if (!cond_ruled())
        return LOAD(sem_timedwait)(s, abs);
    if (!valid_ts(abs))
        return errno_ret(EINVAL);
    return sem_wait_virtual(s, sim_deadline(CLOCK_REALTIME, abs));
}

EXPORT int sem_clockwait(sem_t *s, clockid_t clock, const struct timespec *abs)
{
    if (!cond_ruled())
        return LOAD(sem_clockwait)(s, clock, abs);
    if (!valid_ts(abs) || (clock != CLOCK_REALTIME && clock != CLOCK_MONOTONIC))
        return errno_ret(EINVAL);
    return sem_wait_virtual(s, sim_deadline(clock, abs));
}

/* Barriers (AP_HAL_Linux's threads meet at one before they start their loops): kept here in lockstep,
   since a thread blocked in glibc's would hold the turn. The last to arrive goes on with
   PTHREAD_BARRIER_SERIAL_THREAD, as in glibc; the others when the rule picks them. */
#define MAX_BARRIERS 16
static struct {
    pthread_barrier_t *b;
    unsigned count, arrived;
    uint64_t round;
} barriers[MAX_BARRIERS];

struct barrier_wait {
    int slot;
    uint64_t round;
};

static int barrier_passed(void *w)
{
    struct barrier_wait *bw = w;
    return barriers[bw->slot].round != bw->round;
}

static int barrier_slot(const pthread_barrier_t *b)
{
    for (int i = 0; i < MAX_BARRIERS; i++)
        if (barriers[i].b == b)
            return i;
    return -1;
}

EXPORT int pthread_barrier_init(pthread_barrier_t *b, const pthread_barrierattr_t *attr, unsigned count)
{
    int err = LOAD(pthread_barrier_init)(b, attr, count);
    if (err || !lockstep || !active)
        return err;
    int slot = barrier_slot(b);
    for (int i = 0; i < MAX_BARRIERS && slot < 0; i++)
        if (!barriers[i].b)
            slot = i;
    if (slot >= 0) { /* (more barriers than slots: the rest are glibc's) */
        barriers[slot].b = b;
        barriers[slot].count = count;
        barriers[slot].arrived = 0;
    }
    return 0;
}

EXPORT int pthread_barrier_destroy(pthread_barrier_t *b)
{
    int slot = barrier_slot(b);
    if (slot >= 0)
        barriers[slot].b = NULL;
    return LOAD(pthread_barrier_destroy)(b);
}

EXPORT int pthread_barrier_wait(pthread_barrier_t *b)
{
    int slot = cond_ruled() ? barrier_slot(b) : -1;
    if (slot < 0)
        return LOAD(pthread_barrier_wait)(b);
    if (++barriers[slot].arrived == barriers[slot].count) {
        barriers[slot].arrived = 0;
        barriers[slot].round++;
        return PTHREAD_BARRIER_SERIAL_THREAD;
    }
    struct barrier_wait w = { slot, barriers[slot].round };
    rule_wait(RIG_WAIT_FOREVER, barrier_passed, &w, 0);
    return 0;
}
