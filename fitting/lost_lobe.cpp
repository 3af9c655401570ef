#include "lost_lobe.h"

#include <algorithm>

#include "identifiability.h"

namespace phongfit {

bool showsLobe(const MaterialFit& m) {
    if (m.isUnconstrained("n")) return false;
    for (int c = 0; c < 3; ++c)
        if (m.ksStd[c] > 0 && m.ks[c] >= kLobeConfirmation * m.ksStd[c]) return true;
    return false;
}

std::vector<int> lostLobes(const std::vector<MaterialFit>& before,
                           const std::vector<MaterialFit>& after) {
    std::vector<int> lost;
    for (std::size_t s = 0; s < std::min(before.size(), after.size()); ++s) {
        if (showsLobe(before[s]) && after[s].isUnconstrained("n") && after[s].ksUnconstrained())
            lost.push_back(int(s));
    }
    return lost;
}

}  // namespace phongfit
