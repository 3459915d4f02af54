/* SPDX-License-Identifier: BSD-2-Clause
 * rusage_of OUT COMMAND [ARG...]: run COMMAND and write "peak_rss_kb cpu_seconds" of it to OUT;
 * exits with its status. Its own measurement, from a parent of about 1 MB: Linux gives a process
 * forked from a large parent (a Python benchmark of 44 MB) that parent's resident size as its
 * starting high-water mark, so /bin/true read 44.4 MB from such a parent (issue 46). A process
 * forked from this small one starts from this one's. */
#define _DEFAULT_SOURCE
#include <stdio.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: rusage_of OUT COMMAND [ARG...]\n");
        return 2;
    }
    struct stat target;
    if (stat(argv[1], &target) == 0 && S_ISREG(target.st_mode) && (target.st_mode & 0111)) {
        /* "rusage_of COMMAND ..." without OUT would overwrite COMMAND with two numbers */
        fprintf(stderr, "rusage_of: OUT %s is an executable file, not written (usage: rusage_of OUT COMMAND)\n",
                argv[1]);
        return 2;
    }
    pid_t pid = fork();
    if (pid < 0) {
        perror("rusage_of: fork");
        return 2;
    }
    if (pid == 0) {
        execvp(argv[2], argv + 2);
        perror("rusage_of: exec");
        _exit(127);
    }
    int status = 0;
    struct rusage usage;
    if (wait4(pid, &status, 0, &usage) < 0) {
        perror("rusage_of: wait4");
        return 2;
    }
    FILE *out = fopen(argv[1], "w");
    if (!out) {
        perror("rusage_of: OUT");
        return 2;
    }
    double cpu = (double)usage.ru_utime.tv_sec + usage.ru_utime.tv_usec / 1e6 + (double)usage.ru_stime.tv_sec +
                 usage.ru_stime.tv_usec / 1e6;
    fprintf(out, "%ld %.6f\n", usage.ru_maxrss, cpu);
    fclose(out);
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}
