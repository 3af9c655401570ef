// What memory the process has and may still take, read from Linux (/proc, cgroup v2).
#pragma once

#include <cstddef>

namespace phongfit {

// Bytes the process holds now (resident set), 0 where it cannot be read.
std::size_t residentBytes();
// The same, read from /proc/self/statm open as `statm` (at its start; 0 where it cannot be read).
std::size_t residentBytes(int statm);

// Of residentBytes(), the pages backed by files (RssFile): the program's code and libraries, and
// files mapped for reading, which the kernel brings in as they are first touched and may drop.
std::size_t fileResidentBytes();

// Buffers of 64 kB or more (recorded paths, a fit's per-pixel state) are mapped and unmapped
// whole from then on: glibc's adaptive threshold would serve them from the heap after the first is
// freed, and keep them resident once freed; a threshold of a megabyte left a small fit's per-pixel
// arrays in the heap, freed ones resident among live ones (docs/design/fitter.md, "Memory").
// Called by main, and by the tests that measure the resident set as main leaves it.
void mapLargeBuffers();

// Makes every page of the program's own executable file resident (its code and constant data),
// so that the code a fit first runs is not counted as the fit's memory: a fit's
// memory is then its data, exactly, where the program's pages taken in meanwhile could only be
// bounded (docs/design/fitter.md, "Memory"). Libraries are left as they are.
void residentProgram();

// The most the process has held since it started or since resetPeakResident() (VmHWM), 0 where
// it cannot be read.
std::size_t peakResidentBytes();

// Starts peakResidentBytes() afresh from what the process holds now (Linux' clear_refs "5"; where
// that is not allowed the peak stays the process' own).
void resetPeakResident();

// Bytes the process may still allocate: the smaller of the machine's available memory
// (MemAvailable) and what the cgroup's memory.max leaves; 0 where neither can be read.
std::size_t availableBytes();

}  // namespace phongfit
