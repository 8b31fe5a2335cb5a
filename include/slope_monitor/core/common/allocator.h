// Memory for image work: keep what is freed for reuse.
//
// Matching and rendering allocate and free buffers of megabytes many times
// per photo (pyramids, SIFT scale spaces, LSC windows, decoded images). By
// default glibc serves each of them with a fresh mmap and returns freed
// memory to the system at once, so every photo pays its page faults again.
// Measured with process_bag on the uav_block_replay survey (20 photos of
// 1280 x 960 px, two epochs, tie points, two idle cores, 28 Nov 2026):
//                     wall    CPU (user + sys)   minor faults   peak memory
//   glibc defaults    54-57 s  70-72 s (12 s sys)   1.74 M         480-489 MB
//   this              40 s     55 s (2.9 s sys)     0.33 M         560 MB
// (tie-point stage 21.6 / 18.0 s -> 13.5 / 11.2 s per epoch). Call once, first
// thing in main(), in programs that work on photos; a header of its own so
// that the node shims, which link no slope_monitor library, can call it.
#pragma once

#include <malloc.h>

namespace slope_monitor {

inline void KeepFreedMemoryForReuse() {
  mallopt(M_MMAP_THRESHOLD, 64 << 20);  // [bytes] only larger blocks are mapped on their own
  mallopt(M_TRIM_THRESHOLD, 1 << 30);   // [bytes] free memory kept before returning it
}

}  // namespace slope_monitor
