#include "path_integrator.h"

#include <algorithm>

namespace phongfit {

PathIntegrator::PathIntegrator(const Scene& scene, const EmbreeScene& geometry,
                               const LightSet& lights, std::vector<PhongMaterial> materials,
                               std::vector<int> slots, const PhongSampler<double>& sampler,
                               const PhongSampler<double>& fittedSampler,
                               IntegratorSettings settings)
    : scene_(scene),
      geometry_(geometry),
      lights_(lights),
      materials_(std::move(materials)),
      slots_(std::move(slots)),
      sampler_(sampler),
      fittedSampler_(fittedSampler),
      settings_(settings),
      // Per bounce: lobe choice, 2D direction, roulette, then 3 per light.
      dimensionsPerBounce_(4 + 2 * std::uint32_t(lights.size())),
      nothingOccludes_(scene.shapes.size() <= 2 &&
                       std::ranges::count_if(
                           scene.shapes, [](const ShapeDesc& s) { return !s.areaRadiance; }) == 1 &&
                       std::ranges::count_if(scene.shapes, [](const ShapeDesc& s) {
                           return !s.areaRadiance && s.type == ShapeDesc::Type::Sphere;
                       }) == 1) {
    for (std::size_t s = 0; s < scene.shapes.size(); ++s)
        areaLights_ += lights.lightOfShape(int(s)) >= 0;
}

}  // namespace phongfit
