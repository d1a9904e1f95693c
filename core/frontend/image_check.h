#pragma once
// `marglab datasets check` on a folder with images runs what `run --frontend images` runs before
// it tracks (issue #32: check said ok for folders run refused): the camera models of the
// calibration (a known distortion model with its number of coefficients), then every stereo image
// decoded at the calibration's size — a missing, truncated or wrong-size image, or a folder in
// place of one, is refused here with the file named, not minutes into a run.

#include <cstddef>

#include "core/frontend/image_folder.h"

namespace marglab {

// Returns the number of stereo pairs checked (0: the folder has no images); throws InputError
// naming the file and what was expected.
std::size_t checkImages(const ImageSequence& images);

}  // namespace marglab
