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
 * The pthread objects threads meet at (mutexes, read-write locks, condition variables, semaphores,
 * barriers) are sync.c's.
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
