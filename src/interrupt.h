// SIGINT/SIGTERM become a flag that long loops poll at safe points (tile boundaries, rounds), so an
// interrupted run still writes a valid result of the work done.
#pragma once

namespace phongfit {

// Installs the handler (idempotent); main() does, once. A second signal while the flag is set ends
// the process.
void installInterruptHandler();
bool interruptRequested();
// For tests: set or clear the flag as a signal would.
void setInterruptRequested(bool value);

}  // namespace phongfit
