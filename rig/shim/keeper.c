/*
 * rig-keeper: the DUT's parent. Usage: rig-keeper STATUS_FD LIFELINE_FD GRACE_MS -- CMD ARGS...
 *
 * Why it exists: a DUT may start children that leave its process group (setsid, daemons), ignore
 * SIGTERM, or outlive a rig that was itself killed. The keeper is a subreaper
 * (PR_SET_CHILD_SUBREAPER), so every process the DUT starts, however it detaches, stays in the keeper's
 * subtree; and the keeper ends that whole subtree
 *   - when the rig closes the lifeline (its write end of LIFELINE_FD), which also happens when the rig
 *     dies, even by SIGKILL: SIGTERM to every process, SIGKILL to what is left after GRACE_MS;
 *   - when the DUT's main process exits by itself: what it left behind gets SIGKILL at once.
 * The keeper exits when its subtree is empty.
 *
 * Lines written to STATUS_FD: "exec ERRNO" when CMD could not be started (nothing ran), then
 * "exit WSTATUS" when the DUT's main process has ended (its wait status, as waitpid(2) gives it).
 *
 * The DUT runs in a session of its own (setsid), as before the keeper existed. RIG_KEEPER_PRELOAD
 * becomes the DUT's LD_PRELOAD (the keeper itself runs without the shim). The subtree is read from the
 * kernel's children lists where it keeps them, else from every process in /proc (RIG_KEEPER_FULL_SCAN=1
 * takes that way anyway: the tests try both).
 */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/signalfd.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define MAX_PROCS 4096

static int status_fd = -1;

static void say(const char *what, int value)
{
    char line[64];
    int n = snprintf(line, sizeof line, "%s %d\n", what, value);
    if (status_fd >= 0 && write(status_fd, line, (size_t)n) < 0)
        status_fd = -1; /* the rig is gone; the lifeline tells us too */
}

static long now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1000L + ts.tv_nsec / 1000000L;
}

/* The pids of the keeper's subtree (excluding the keeper), read from every /proc/PID/stat: where the
   kernel keeps no children lists (subtree_walk). Zombies left out (they are dead already and only wait
   for their parent's waitpid). Returns how many. */
static int subtree(pid_t root, pid_t *out, int cap)
{
    static pid_t pid[MAX_PROCS], ppid[MAX_PROCS];
    int n = 0;
    DIR *d = opendir("/proc");
    if (!d)
        return 0;
    struct dirent *e;
    while ((e = readdir(d)) && n < MAX_PROCS) {
        char *end;
        long p = strtol(e->d_name, &end, 10);
        if (*end || p <= 0)
            continue;
        char path[64], buf[512];
        snprintf(path, sizeof path, "/proc/%ld/stat", p);
        int fd = open(path, O_RDONLY | O_CLOEXEC);
        if (fd < 0)
            continue;
        ssize_t k = read(fd, buf, sizeof buf - 1);
        close(fd);
        if (k <= 0)
            continue;
        buf[k] = 0;
        char *rp = strrchr(buf, ')'); /* the command name may hold spaces and parentheses */
        char state;
        int parent;
        if (!rp || sscanf(rp + 1, " %c %d", &state, &parent) != 2 || state == 'Z')
            continue;
        pid[n] = (pid_t)p;
        ppid[n] = (pid_t)parent;
        n++;
    }
    closedir(d);
    int m = 0, grew = 1;
    static char in[MAX_PROCS];
    memset(in, 0, sizeof in);
    while (grew) { /* a process is ours if its parent is the keeper or one of ours */
        grew = 0;
        for (int i = 0; i < n; i++) {
            if (in[i])
                continue;
            int ours = ppid[i] == root;
            for (int j = 0; j < n && !ours; j++)
                ours = in[j] && pid[j] == ppid[i];
            if (ours && m < cap) {
                in[i] = 1;
                out[m++] = pid[i];
                grew = 1;
            }
        }
    }
    return m;
}

/* The pids in one /proc/PID/task/TID/children file appended to out (from out[n]); returns the new count */
static int read_children(const char *path, pid_t *out, int n, int cap)
{
    static char buf[65536]; /* (MAX_PROCS pids of up to 7 digits and a space fit) */
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return n; /* the task ended meanwhile */
    size_t len = 0;
    ssize_t k;
    while (len < sizeof buf - 1 && (k = read(fd, buf + len, sizeof buf - 1 - len)) > 0)
        len += (size_t)k;
    close(fd);
    buf[len] = 0;
    for (char *c = buf, *end; n < cap; c = end) {
        long p = strtol(c, &end, 10);
        if (end == c)
            break;
        if (p > 0)
            out[n++] = (pid_t)p;
    }
    return n;
}

/* The subtree read from the kernel's children lists (/proc/PID/task/TID/children, CONFIG_PROC_CHILDREN),
   each process's threads' lists from the keeper down: only the subtree's own files, where subtree()
   reads every process's on the machine (0.7 ms with 67 processes on a CI VM, at the end of every run).
   Zombies are in it: a signal to one does nothing. -1 when the kernel keeps no such lists. */
static int subtree_walk(pid_t root, pid_t *out, int cap)
{
    char path[96];
    snprintf(path, sizeof path, "/proc/%d/task/%d/children", (int)root, (int)root);
    if (access(path, R_OK) != 0)
        return -1;
    int n = 0;
    for (int i = -1; i < n; i++) { /* out[] is the queue too: each one's children go after the rest */
        pid_t p = i < 0 ? root : out[i];
        snprintf(path, sizeof path, "/proc/%d/task", (int)p);
        DIR *d = opendir(path);
        if (!d)
            continue; /* it ended meanwhile */
        struct dirent *e;
        while ((e = readdir(d)) && n < cap) {
            if (e->d_name[0] < '0' || e->d_name[0] > '9')
                continue;
            snprintf(path, sizeof path, "/proc/%d/task/%.20s/children", (int)p, e->d_name);
            n = read_children(path, out, n, cap);
        }
        closedir(d);
    }
    return n;
}

static int full_scan; /* RIG_KEEPER_FULL_SCAN=1: subtree() even where the lists are kept (its tests) */

static int signal_subtree(int sig)
{
    static pid_t pids[MAX_PROCS];
    int n = full_scan ? -1 : subtree_walk(getpid(), pids, MAX_PROCS);
    if (n < 0)
        n = subtree(getpid(), pids, MAX_PROCS);
    for (int i = 0; i < n; i++)
        kill(pids[i], sig);
    return n;
}

int main(int argc, char **argv)
{
    if (argc < 6 || strcmp(argv[4], "--") != 0) {
        fprintf(stderr, "usage: rig-keeper STATUS_FD LIFELINE_FD GRACE_MS -- CMD ARGS...\n");
        return 2;
    }
    status_fd = atoi(argv[1]);
    int lifeline = atoi(argv[2]);
    long grace_ms = atol(argv[3]);
    char **cmd = argv + 5;
    if (prctl(PR_SET_CHILD_SUBREAPER, 1) < 0) {
        fprintf(stderr, "rig-keeper: PR_SET_CHILD_SUBREAPER: %s\n", strerror(errno));
        return 2;
    }
    sigset_t mask, old;
    sigemptyset(&mask);
    sigaddset(&mask, SIGCHLD);
    sigaddset(&mask, SIGTERM);
    sigaddset(&mask, SIGINT);
    sigaddset(&mask, SIGHUP);
    sigprocmask(SIG_BLOCK, &mask, &old);
    int sfd = signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK);
    int exec_pipe[2];
    if (sfd < 0 || pipe2(exec_pipe, O_CLOEXEC) < 0) {
        fprintf(stderr, "rig-keeper: %s\n", strerror(errno));
        return 2;
    }
    const char *scan = getenv("RIG_KEEPER_FULL_SCAN");
    full_scan = scan && strcmp(scan, "1") == 0;
    pid_t main_pid = fork();
    if (main_pid < 0) {
        say("exec", errno);
        return 0;
    }
    if (main_pid == 0) {
        sigprocmask(SIG_SETMASK, &old, NULL);
        setsid();
        close(status_fd);
        close(lifeline);
        const char *preload = getenv("RIG_KEEPER_PRELOAD");
        if (preload) {
            setenv("LD_PRELOAD", preload, 1);
            unsetenv("RIG_KEEPER_PRELOAD");
        }
        execvp(cmd[0], cmd);
        int err = errno;
        if (write(exec_pipe[1], &err, sizeof err) < 0)
            _exit(127);
        _exit(127);
    }
    close(exec_pipe[1]);
    int err = 0;
    if (read(exec_pipe[0], &err, sizeof err) == (ssize_t)sizeof err) {
        waitpid(main_pid, NULL, 0);
        say("exec", err);
        return 0;
    }
    close(exec_pipe[0]);

    int main_done = 0, stopping = 0, killed = 0;
    long kill_at = 0;
    for (;;) {
        /* reap: the main process (report it), and every orphan that was reparented to us */
        for (;;) {
            int ws;
            pid_t p = waitpid(-1, &ws, WNOHANG);
            if (p <= 0) {
                if (p < 0 && errno == ECHILD && main_done)
                    return 0; /* the subtree is empty */
                break;
            }
            if (p == main_pid) {
                main_done = 1;
                say("exit", ws);
                if (!stopping) { /* it ended by itself: what it left behind goes now */
                    stopping = killed = 1;
                    signal_subtree(SIGKILL);
                }
            }
        }
        if (stopping && !killed && now_ms() >= kill_at) {
            killed = 1;
            signal_subtree(SIGKILL);
        }
        if (killed)
            signal_subtree(SIGKILL); /* anything forked since the last round, too */
        struct pollfd fds[2] = { { sfd, POLLIN, 0 }, { lifeline, POLLIN, 0 } };
        int timeout = -1;
        if (stopping && !killed)
            timeout = (int)(kill_at - now_ms() > 0 ? kill_at - now_ms() : 0);
        else if (killed)
            timeout = 50; /* processes being killed: look again soon */
        int nfds = lifeline >= 0 ? 2 : 1;
        if (poll(fds, (nfds_t)nfds, timeout) < 0 && errno != EINTR)
            return 2;
        if (fds[0].revents & POLLIN) {
            struct signalfd_siginfo si;
            while (read(sfd, &si, sizeof si) == (ssize_t)sizeof si)
                if (si.ssi_signo != SIGCHLD && !stopping) { /* asked to stop the DUT */
                    stopping = 1;
                    kill_at = now_ms() + grace_ms;
                    signal_subtree(SIGTERM);
                }
        }
        if (nfds == 2 && fds[1].revents) {
            char c;
            if (read(lifeline, &c, 1) <= 0) { /* EOF: the rig closed it, or died */
                close(lifeline);
                lifeline = -1;
                if (!stopping) {
                    stopping = 1;
                    kill_at = now_ms() + grace_ms;
                    signal_subtree(SIGTERM);
                }
            }
        }
    }
}
