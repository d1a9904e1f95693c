#pragma once
// Between the estimator and the results file: what the estimator reports of a frame and of a
// keyframe marginalization (core/estimator/estimator.h) becomes the file's records
// (core/io/results_file.h). The estimator knows nothing of the file; the file nothing of the
// estimator.

#include <cstdint>

#include "core/estimator/estimator.h"
#include "core/io/results_file.h"

namespace marglab {

// The /frames row of a frame (p_gt is left to the caller: the estimator has no ground truth).
FrameRecord toFrameRecord(const FrameResult& result);

// The /sparsify row of a keyframe marginalization at row frame_index of /frames.
SparsifyRecord toSparsifyRecord(const SparsifyEvent& event, std::int64_t frame_index,
                                std::int64_t t_ns);

}  // namespace marglab
