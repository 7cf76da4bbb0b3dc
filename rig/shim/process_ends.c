/*
 * The calls at which a process ends, becomes another program, starts one or waits for one. In lockstep
 * the shim holds the process's notices (PWM writes, a sleep that went ahead) until its next message
 * (link.c, hold_msg); here they go first, since after these calls that message may never come: a shell
 * writes a PWM attribute with its builtin echo, then runs `sleep` and ends with _exit. exit() and fork
 * are covered at start-up (a destructor, pthread_atfork). glibc's own exec, spawn, system and popen
 * reach the kernel through internal names, so each public one is interposed here. Part of rigshim.c
 * (one translation unit): see its top comment.
 */

#define FLUSH_THEN(ret, name, params, args)       \
    EXPORT ret name params                        \
    {                                             \
        static ret(*real) params;                 \
        send_held_now();                          \
        if (!real)                                \
            real = (ret(*) params)resolve(#name); \
        return real args;                         \
    }

FLUSH_THEN(int, execve, (const char *p, char *const a[], char *const e[]), (p, a, e))
FLUSH_THEN(int, execv, (const char *p, char *const a[]), (p, a))
FLUSH_THEN(int, execvp, (const char *p, char *const a[]), (p, a))
FLUSH_THEN(int, execvpe, (const char *p, char *const a[], char *const e[]), (p, a, e))
FLUSH_THEN(int, fexecve, (int fd, char *const a[], char *const e[]), (fd, a, e))
FLUSH_THEN(int, posix_spawn,
           (pid_t * pid, const char *p, const posix_spawn_file_actions_t *fa, const posix_spawnattr_t *at,
            char *const a[], char *const e[]),
           (pid, p, fa, at, a, e))
FLUSH_THEN(int, posix_spawnp,
           (pid_t * pid, const char *p, const posix_spawn_file_actions_t *fa, const posix_spawnattr_t *at,
            char *const a[], char *const e[]),
           (pid, p, fa, at, a, e))
FLUSH_THEN(int, system, (const char *cmd), (cmd))
FLUSH_THEN(FILE *, popen, (const char *cmd, const char *mode), (cmd, mode))
FLUSH_THEN(pid_t, wait, (int *status), (status))
FLUSH_THEN(pid_t, waitpid, (pid_t pid, int *status, int options), (pid, status, options))
FLUSH_THEN(pid_t, wait3, (int *status, int options, struct rusage *ru), (status, options, ru))
FLUSH_THEN(pid_t, wait4, (pid_t pid, int *status, int options, struct rusage *ru), (pid, status, options, ru))
FLUSH_THEN(int, waitid, (idtype_t t, id_t id, siginfo_t *info, int options), (t, id, info, options))

EXPORT void _exit(int status)
{
    static void (*real)(int);
    send_held_now();
    if (!real)
        real = (void (*)(int))resolve("_exit");
    real(status);
    __builtin_unreachable();
}

EXPORT void _Exit(int status) { _exit(status); }

/* The execl family takes its arguments as varargs: gathered into the array execve and execvp take
   (and execle's environment, after the NULL that ends them). */
static char **gather_args(const char *first, va_list ap, char ***envp)
{
    size_t n = 0;
    if (first) {
        va_list count;
        va_copy(count, ap);
        for (n = 1; va_arg(count, char *); n++)
            ;
        va_end(count);
    }
    char **argv = malloc((n + 1) * sizeof *argv);
    if (!argv)
        return NULL;
    for (size_t i = 0; i < n; i++)
        argv[i] = i ? va_arg(ap, char *) : (char *)first;
    argv[n] = NULL;
    if (first)
        (void)va_arg(ap, char *); /* the NULL that ends them */
    if (envp)
        *envp = va_arg(ap, char **);
    return argv;
}

#define EXECL(name, with_env, call)                                 \
    EXPORT int name(const char *path, const char *arg, ...)         \
    {                                                               \
        va_list ap;                                                 \
        va_start(ap, arg);                                          \
        char **env = environ;                                       \
        char **argv = gather_args(arg, ap, with_env ? &env : NULL); \
        va_end(ap);                                                 \
        if (!argv)                                                  \
            return errno_ret(ENOMEM);                               \
        int r = call;                                               \
        int err = errno;                                            \
        free(argv);                                                 \
        errno = err;                                                \
        return r;                                                   \
    }

EXECL(execl, 0, execve(path, argv, env))
EXECL(execle, 1, execve(path, argv, env))
EXECL(execlp, 0, execvp(path, argv))
