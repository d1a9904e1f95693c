#pragma once
// The trust boundary for HDF5 files a user hands in: the track file of `run --tracks` and
// `datasets ... --tracks`, and the results files read by `tables`, `eigdump` and the sweep's
// resume (docs/design.md §11). libhdf5 (Debian's 1.10) trusts what a file says about itself:
// fuzzing marglab's track reader made it loop forever in a global heap, allocate 4–10 GB on the
// word of a 44 KB file, and read and write outside its own buffers (fuzz/README.md lists the
// inputs). A guard in front of each of its decoders would be a second HDF5 reader. Instead a file
// is read twice:
//   1. in a forked child, under limits — address space (RLIMIT_AS), CPU time (RLIMIT_CPU) and a
//      wall-clock timeout — by the caller's own reader, whose result is discarded;
//   2. by the caller, only once the child has ended normally.
// The child is a copy of this process at the fork and runs the same deterministic code on the same
// bytes, so the caller's read replays one that ended: what the child did not survive — a crash
// (libhdf5 or the reader), a loop, a request beyond the limit — is an InputError naming the file
// and what happened, and the caller never meets it. An exception of the read in the child is the
// answer too — an InputError thrown here as the child threw it, another as "reading it failed: …" —
// since it may come from an allocation libhdf5 reported as failed under the limit, which the
// caller, without the limit, would make. What no limit sees is a stray read or write that neither
// crashes nor changes what the reader checks: the caller then reads the same values as the child
// (its own checks still apply).
//
// The address space is limited to what the process has mapped at the fork plus the budget: what
// a process maps before reading (libraries, thread stacks, malloc arenas) varies, and under
// AddressSanitizer it is terabytes of shadow and allocator space, reserved at start-up. Large
// allocations map new memory in both cases (ASan's secondary allocator), so the budget bounds them
// alike; under ASan an allocation refused by the limit returns null (allocator_may_return_null=1,
// which scripts/run_sanitizers.sh sets) or ends the child with ASan's out-of-memory report — an
// InputError here either way.
//
// Call it where no other thread is inside libhdf5 (its global lock would stay held in the child);
// the child ignores SIGINT and SIGTERM (stopping is the caller's decision) and dies with the
// thread that forked it (PR_SET_PDEATHSIG).

#include <cstdint>
#include <functional>
#include <string>

namespace marglab::h5 {

struct ReadLimits {
  // Beyond what is mapped at the fork: a whole KITTI sequence's track file, decoded, takes a few
  // hundred MB, a results file a few MB; a claim of gigabytes fails at once, untouched.
  std::uint64_t address_space_bytes = std::uint64_t{1} << 30;
  int cpu_seconds = 20;   // a read of the largest file takes well under a second
  int wall_seconds = 60;  // a child starved of CPU by a busy machine is not stopped early
};

// Runs `read` (a read of the file at `path`) in a forked child under `limits` and returns when it
// ended normally; otherwise throws the child's InputError as it was, or InputError(path, 0, what
// happened): "reading it took more than 20 s of CPU time (its reader was stopped: …)", "reading
// it crashed (signal 11, Segmentation fault): …", "reading it needed more than 1 GiB of memory: …".
void checkReadableInChild(const std::string& path, const std::function<void()>& read,
                          const ReadLimits& limits = {});

}  // namespace marglab::h5
