// What memory the process has and may still take, read from Linux (/proc, cgroup v2).
#pragma once

#include <cstddef>

namespace phongfit {

// Bytes the process holds now (resident set), 0 where it cannot be read.
std::size_t residentBytes();

// Of residentBytes(), the pages backed by files (RssFile): the program's code and libraries, and
// files mapped for reading, which the kernel brings in as they are first touched and may drop.
std::size_t fileResidentBytes();

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
