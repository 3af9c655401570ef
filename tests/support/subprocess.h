// Runs the phongfit executable as a user would, for end-to-end tests: arguments without a shell,
// stdout and stderr captured. For kill tests, signals are sent once the child has installed its
// handler and a condition on its progress holds (text it printed, a file it wrote, time since the
// handler), so the tests do not depend on the machine's speed (sanitizer builds are several times
// slower). A watchdog kills the child if it outlives the plan's limit.
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace phongfit::test {

struct ProcessResult {
    int exitCode = -1;  // -1 if killed by a signal
    int signal = 0;
    std::string out, err;
};

// Whether the process has a handler for `signal` (the SigCgt mask of /proc/PID/status).
inline bool catchesSignal(pid_t pid, int signal) {
    std::ifstream status("/proc/" + std::to_string(pid) + "/status");
    for (std::string line; std::getline(status, line);)
        if (line.starts_with("SigCgt:"))
            return std::stoull(line.substr(7), nullptr, 16) >> (signal - 1) & 1;
    return false;
}

// A condition that holds `delay` after it is first asked.
inline std::function<bool(const std::string&, const std::string&)> after(
    std::chrono::milliseconds delay) {
    auto start = std::make_shared<std::optional<std::chrono::steady_clock::time_point>>();
    return [=](const std::string&, const std::string&) {
        const auto now = std::chrono::steady_clock::now();
        if (!*start) *start = now;
        return now - **start >= delay;
    };
}

struct SignalPlan {
    // Polled every 10 ms with the output so far, once the child catches signals[0] (at once for
    // SIGKILL); the signals go when it returns true.
    std::function<bool(const std::string& out, const std::string& err)> when;
    std::vector<int> signals;  // sent in turn, `gap` apart
    std::chrono::milliseconds gap{50};
    std::chrono::milliseconds limit{std::chrono::minutes(5)};  // with signals to send
};

inline ProcessResult runProcess(const std::vector<std::string>& args, const SignalPlan& plan = {}) {
    int outPipe[2], errPipe[2];
    if (pipe(outPipe) != 0 || pipe(errPipe) != 0) return {};
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, outPipe[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&actions, errPipe[1], STDERR_FILENO);
    posix_spawn_file_actions_addclose(&actions, outPipe[0]);
    posix_spawn_file_actions_addclose(&actions, errPipe[0]);
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    pid_t pid;
    const int rc = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(outPipe[1]);
    close(errPipe[1]);
    ProcessResult result;
    if (rc != 0) {
        close(outPipe[0]);
        close(errPipe[0]);
        result.err = "could not start " + args[0];
        return result;
    }
    const auto start = std::chrono::steady_clock::now();
    std::size_t sent = 0;
    std::chrono::steady_clock::time_point lastSent;
    bool triggered = false, killed = false;
    pollfd fds[2] = {{outPipe[0], POLLIN, 0}, {errPipe[0], POLLIN, 0}};
    int open = 2;
    while (open > 0) {
        const auto now = std::chrono::steady_clock::now();
        if (!triggered && !plan.signals.empty() &&
            (plan.signals[0] == SIGKILL || catchesSignal(pid, plan.signals[0])) &&
            plan.when(result.out, result.err))
            triggered = true;
        if (triggered && sent < plan.signals.size() && (sent == 0 || now - lastSent >= plan.gap)) {
            kill(pid, plan.signals[sent++]);
            lastSent = now;
        }
        if (!killed && !plan.signals.empty() && now - start > plan.limit) {
            kill(pid, SIGKILL);
            killed = true;
        }
        if (poll(fds, 2, 10) < 0) break;
        for (int i = 0; i < 2; ++i) {
            if (fds[i].fd < 0 || !(fds[i].revents & (POLLIN | POLLHUP))) continue;
            char buffer[4096];
            const ssize_t n = read(fds[i].fd, buffer, sizeof buffer);
            if (n <= 0) {
                close(fds[i].fd);
                fds[i].fd = -1;
                --open;
            } else {
                (i == 0 ? result.out : result.err).append(buffer, std::size_t(n));
            }
        }
    }
    int status = 0;
    waitpid(pid, &status, 0);
    if (WIFEXITED(status)) result.exitCode = WEXITSTATUS(status);
    if (WIFSIGNALED(status)) result.signal = WTERMSIG(status);
    return result;
}

// The phongfit executable under test with these arguments (PHONGFIT_EXE, which every test has).
inline ProcessResult runPhongfit(const std::vector<std::string>& args,
                                 const SignalPlan& plan = {}) {
    std::vector<std::string> command = {PHONGFIT_EXE};
    command.insert(command.end(), args.begin(), args.end());
    return runProcess(command, plan);
}

}  // namespace phongfit::test
