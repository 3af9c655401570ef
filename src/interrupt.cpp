#include "interrupt.h"

#include <atomic>
#include <csignal>
#include <cstdlib>

namespace phongfit {
namespace {

std::atomic<bool> requested{false};

extern "C" void onSignal(int sig) {
    if (requested.exchange(true)) std::_Exit(128 + sig);
}

}  // namespace

void installInterruptHandler() {
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
}

bool interruptRequested() { return requested.load(std::memory_order_relaxed); }

void setInterruptRequested(bool value) { requested.store(value); }

}  // namespace phongfit
