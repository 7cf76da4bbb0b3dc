/* A C DUT for `rig exec`: sets up pwm0, sleeps 10 ms, writes a duty cycle, then leaves in the way
   argv[1] names (a return from main, _exit, an exec, a spawn, a fork, system) with no other call
   between the write and the leaving. The session must still see that write, stamped when it was made:
   in lockstep the shim holds notices until the process's next message. "sleep" sleeps twice more
   (a request) and returns: the reference. */
#define _GNU_SOURCE
#include <fcntl.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define PWM "/sys/class/pwm/pwmchip0"

extern char **environ;

static void put(const char *path, const char *value)
{
    int fd = open(path, O_WRONLY);
    if (fd < 0 || write(fd, value, strlen(value)) != (ssize_t)strlen(value) || close(fd) != 0) {
        perror(path);
        exit(2);
    }
}

int main(int argc, char **argv)
{
    if (argc != 2)
        return 2;
    const char *how = argv[1];
    put(PWM "/export", "0");
    put(PWM "/pwm0/period", "2500000");
    put(PWM "/pwm0/duty_cycle", "1000000");
    put(PWM "/pwm0/enable", "1");
    struct timespec ms10 = { 0, 10000000 };
    nanosleep(&ms10, NULL);
    int fd = open(PWM "/pwm0/duty_cycle", O_WRONLY);
    if (fd < 0 || write(fd, "1700000", 7) != 7)
        return 2;
    char *true_argv[] = { "true", NULL };
    pid_t pid;
    int status;
    if (!strcmp(how, "return"))
        return 0;
    if (!strcmp(how, "_exit"))
        _exit(0);
    if (!strcmp(how, "execl"))
        execl("/bin/true", "true", (char *)NULL);
    else if (!strcmp(how, "execle"))
        execle("/bin/true", "true", (char *)NULL, environ);
    else if (!strcmp(how, "execvp"))
        execvp("true", true_argv);
    else if (!strcmp(how, "posix_spawnp")) {
        if (posix_spawnp(&pid, "true", NULL, NULL, true_argv, environ) == 0 && waitpid(pid, &status, 0) == pid)
            _exit(0);
    } else if (!strcmp(how, "fork")) {
        pid = fork();
        if (pid == 0)
            _exit(0);
        if (pid > 0 && waitpid(pid, &status, 0) == pid)
            _exit(0);
    } else if (!strcmp(how, "vfork")) {
        pid = vfork();
        if (pid == 0) {
            execv("/bin/true", true_argv);
            _exit(127);
        }
        if (pid > 0 && waitpid(pid, &status, 0) == pid)
            _exit(0);
    } else if (!strcmp(how, "system")) {
        if (system("true") == 0)
            _exit(0);
    } else if (!strcmp(how, "sleep")) {
        struct timespec ms1 = { 0, 1000000 };
        nanosleep(&ms1, NULL);
        nanosleep(&ms1, NULL);
        return 0;
    }
    return 3;
}
