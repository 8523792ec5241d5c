// Walks along the lines of LineSteps (one label's direction through the nodes): what the
// expansion moves and the part-removing moves ask of a labeling to keep each label's nodes one
// stretch per line. A line that loops back counts as leaving the nodes.
#pragma once

#include <cstdint>
#include <vector>

namespace dhfcast::detail {

// ahead[i] = 1 when the line from node i along `step` meets a node labeled l after i, else 0;
// for every node at once, each step walked once. `stack` is scratch.
inline void mark_label_ahead(const std::vector<std::int32_t>& step,
                             const std::vector<std::int32_t>& label, std::int32_t l,
                             std::vector<std::int8_t>& ahead, std::vector<std::int32_t>& stack) {
  const auto n = static_cast<std::int32_t>(step.size());
  constexpr std::int8_t kUnknown = -1, kOnStack = -2;
  ahead.assign(n, kUnknown);
  for (std::int32_t i = 0; i < n; ++i) {
    if (ahead[i] != kUnknown) continue;
    stack.clear();
    for (std::int32_t j = i; j >= 0 && ahead[j] == kUnknown; j = step[j]) {
      ahead[j] = kOnStack;
      stack.push_back(j);
    }
    for (auto p = stack.rbegin(); p != stack.rend(); ++p) {
      const std::int32_t next = step[*p];
      ahead[*p] = next >= 0 && (label[next] == l || ahead[next] == 1) ? 1 : 0;
    }
  }
}

// Whether the line from node i along `step` meets label l after i; with `after_leaving`, only
// once it has met another label first (for l node i's own: the line leaves l and meets it again).
inline bool line_meets(const std::vector<std::int32_t>& step, std::int32_t i, std::int32_t l,
                       const std::vector<std::int32_t>& labels, bool after_leaving) {
  bool left = !after_leaving;
  std::size_t walked = 0;
  for (std::int32_t j = step[i]; j >= 0 && walked < step.size(); j = step[j], ++walked) {
    if (labels[j] != l)
      left = true;
    else if (left)
      return true;
  }
  return false;
}

}  // namespace dhfcast::detail
