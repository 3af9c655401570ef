#include "image_error.h"

#include <algorithm>
#include <cmath>

namespace phongfit {

ImageError imageError(const std::vector<float>& image, const std::vector<float>& reference) {
    double squared = 0, relative = 0;
    for (std::size_t i = 0; i < image.size(); ++i) {
        const double d = double(image[i]) - reference[i];
        squared += d * d;
        relative += d * d / (double(reference[i]) * reference[i] + kRelMseEpsilon);
    }
    const double count = double(std::max<std::size_t>(image.size(), 1));
    return {std::sqrt(squared / count), relative / count};
}

}  // namespace phongfit
