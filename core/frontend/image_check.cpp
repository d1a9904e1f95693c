#include "core/frontend/image_check.h"

#include "core/frontend/camera_model.h"
#include "core/frontend/optical_flow.h"

namespace marglab {

std::size_t checkImages(const ImageSequence& images) {
  if (!images.images) return 0;
  const Sequence& seq = images.sequence;
  cameraModelFromCalib<double>(seq.calib.cam0, seq.calib_source);
  cameraModelFromCalib<double>(seq.calib.cam1, seq.calib_source);
  const StereoImageList& list = *images.images;
  for (std::size_t i = 0; i < list.size(); ++i) {
    readGreyImage(list.left[i], seq.calib.cam0.width, seq.calib.cam0.height);
    readGreyImage(list.right[i], seq.calib.cam1.width, seq.calib.cam1.height);
  }
  return list.size();
}

}  // namespace marglab
