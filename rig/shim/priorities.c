/*
 * Priorities and memory locking. In lockstep the rig's rule decides which DUT thread runs (threads.c),
 * so a real-time policy (SCHED_FIFO, SCHED_RR), a priority and mlockall are accepted and recorded, not
 * applied: applied, a SCHED_FIFO thread that takes the shim's lock again at once starves the others
 * on the one core lockstep pins the DUT to. Each request is a note (the run's log at its sim time, the
 * run's notes in result.json, once per distinct text), naming the thread by its name, which the
 * program sets and so is the same in every run. In real time every call passes through: applied where
 * the kernel permits, refused where it does not, as without the rig. Part of rigshim.c (one
 * translation unit): see its top comment.
 */

static int recorded_only(void) { return active && lockstep; }

static const char *policy_name(int policy)
{
    switch (policy & ~SCHED_RESET_ON_FORK) {
    case SCHED_FIFO:
        return "SCHED_FIFO";
    case SCHED_RR:
        return "SCHED_RR";
    case SCHED_OTHER:
        return "SCHED_OTHER";
    case SCHED_BATCH:
        return "SCHED_BATCH";
    case SCHED_IDLE:
        return "SCHED_IDLE";
    default:
        return NULL;
    }
}

static int record_policy_for(const char *call, const char *whose, const char *thread, int policy,
                             const struct sched_param *param);

/* A policy request in lockstep: EINVAL as the kernel gives for an unknown policy or a priority outside
   the policy's range, else recorded (0). */
static int record_policy(const char *call, pthread_t who, int policy, const struct sched_param *param)
{
    char thread[16] = "?";
    pthread_getname_np(who, thread, sizeof thread);
    return record_policy_for(call, "thread", thread, policy, param);
}

static int record_policy_for(const char *call, const char *whose, const char *thread, int policy,
                             const struct sched_param *param)
{
    const char *name = policy_name(policy);
    if (!name || !param)
        return EINVAL;
    int lo = sched_get_priority_min(policy & ~SCHED_RESET_ON_FORK);
    int hi = sched_get_priority_max(policy & ~SCHED_RESET_ON_FORK);
    if (param->sched_priority < lo || param->sched_priority > hi)
        return EINVAL;
    note("priority recorded, not applied (lockstep schedules the threads): %s %s priority %d for %s '%s'", call, name,
         param->sched_priority, whose, thread);
    return 0;
}

/* sched_setscheduler's pid: 0 or this process's own threads are this process's (recorded); another
   process's pass through (the shim speaks only for its own). */
static int own_task(pid_t pid) { return pid == 0 || pid == self_pid() || pid == gettid(); }

static int real_time_policy(int policy)
{
    policy &= ~SCHED_RESET_ON_FORK;
    return policy == SCHED_FIFO || policy == SCHED_RR;
}

/* The ordinary policies (SCHED_OTHER, SCHED_BATCH, SCHED_IDLE) are applied in lockstep too: they cannot
   starve a thread of the one core, and the rule schedules whatever they are. */
EXPORT int sched_setscheduler(pid_t pid, int policy, const struct sched_param *param)
{
    if (!recorded_only() || !own_task(pid) || !real_time_policy(policy))
        return LOAD(sched_setscheduler)(pid, policy, param);
    int err = record_policy("sched_setscheduler", pthread_self(), policy, param);
    return err ? errno_ret(err) : 0;
}

EXPORT int sched_setparam(pid_t pid, const struct sched_param *param)
{
    if (!recorded_only() || !own_task(pid))
        return LOAD(sched_setparam)(pid, param);
    if (!param || param->sched_priority == 0)
        return param ? 0 : errno_ret(EINVAL);
    int err = record_policy("sched_setparam", pthread_self(), SCHED_FIFO, param);
    return err ? errno_ret(err) : 0;
}

EXPORT int pthread_setschedparam(pthread_t thread, int policy, const struct sched_param *param)
{
    if (!recorded_only() || !real_time_policy(policy))
        return LOAD(pthread_setschedparam)(thread, policy, param);
    return record_policy("pthread_setschedparam", thread, policy, param);
}

EXPORT int pthread_setschedprio(pthread_t thread, int prio)
{
    if (!recorded_only())
        return LOAD(pthread_setschedprio)(thread, prio);
    struct sched_param param = { .sched_priority = prio };
    return prio ? record_policy("pthread_setschedprio", thread, SCHED_FIFO, &param) : 0;
}

EXPORT int mlockall(int flags)
{
    if (!recorded_only())
        return LOAD(mlockall)(flags);
    if (!flags || (flags & ~(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT)))
        return errno_ret(EINVAL);
    note("mlockall recorded, not applied (lockstep: no real deadline to miss)");
    return 0;
}

EXPORT int munlockall(void) { return recorded_only() ? 0 : LOAD(munlockall)(); }

/* pthread_create's attributes: an explicit SCHED_FIFO or SCHED_RR policy (ArduPilot's Linux HAL asks for
   one per thread) makes the kernel refuse the thread without CAP_SYS_NICE. In lockstep the request is
   recorded and the thread inherits its creator's policy: *copy is attr so changed (1), or attr is left
   as it is (0). */
static int lockstep_attr(const pthread_attr_t *attr, pthread_attr_t *copy)
{
    int inherit, policy;
    struct sched_param param;
    if (!recorded_only() || !attr || pthread_attr_getinheritsched(attr, &inherit) ||
        inherit != PTHREAD_EXPLICIT_SCHED || pthread_attr_getschedpolicy(attr, &policy) || !real_time_policy(policy) ||
        pthread_attr_getschedparam(attr, &param))
        return 0;
    char creator[16] = "?";
    pthread_getname_np(pthread_self(), creator, sizeof creator);
    record_policy_for("pthread_create", "a thread created by", creator, policy, &param);
    *copy = *attr; /* (glibc's attr holds a pointer to a cpuset it frees: the copy is never destroyed) */
    pthread_attr_setinheritsched(copy, PTHREAD_INHERIT_SCHED);
    return 1;
}
