// Uses the installed libraries through their installed headers (test/install/consumer/CMakeLists.txt):
// an OpenCV round trip through the vision core, a generated message type, and the address of a
// sim_picture function, so that the link needs that library too. Prints "install consumer ok", exit 0.
#include <cstdio>

#include <textile_handling/RecognitionResult.h>

#include "textile_handling/sim/rest_shape_picture.h"
#include "textile_handling/vision/mask_cv.h"

int main() {
  textile_handling::vision::BitMask mask(4, 3);
  mask.set(1, 2);
  const cv::Mat image = textile_handling::vision::toMat(mask);
  const textile_handling::vision::BitMask back = textile_handling::vision::fromMat(image);
  textile_handling::RecognitionResult result;
  result.success = back.get(1, 2) && !back.get(0, 0);
  using PictureWriter = decltype(&textile_handling::writeRestShapePicture);
  volatile PictureWriter picture_writer = &textile_handling::writeRestShapePicture;
  if (!result.success || image.rows != 3 || image.cols != 4 || picture_writer == nullptr) {
    std::printf("install consumer: wrong round trip\n");
    return 1;
  }
  std::printf("install consumer ok\n");
  return 0;
}
