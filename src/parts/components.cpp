#include "components.h"

namespace dhfcast::detail {

std::vector<std::int32_t> label_components(const TetMesh& tets,
                                           const std::vector<std::int32_t>& label,
                                           const std::vector<std::int32_t>& region,
                                           std::int32_t& num_components) {
  const std::int32_t n = static_cast<std::int32_t>(tets.tets.size());
  std::vector<std::int32_t> component(n, -1);
  std::vector<std::int32_t> stack;
  num_components = 0;
  for (std::int32_t seed = 0; seed < n; ++seed) {
    if (component[seed] >= 0) continue;
    component[seed] = num_components;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const std::int32_t t = stack.back();
      stack.pop_back();
      for (const std::int32_t u : tets.neighbors[t]) {
        if (u < 0 || component[u] >= 0 || label[u] != label[t] || region[u] != region[t]) continue;
        component[u] = num_components;
        stack.push_back(u);
      }
    }
    ++num_components;
  }
  return component;
}

}  // namespace dhfcast::detail
