#include "timing/counters.hpp"

namespace hp {

void Counters::set(const std::string& pass, const std::string& name, std::uint64_t value) {
  passes_[pass][name] = value;
}

void Counters::add(const std::string& pass, const std::string& name, std::uint64_t value) {
  passes_[pass][name] += value;
}

void Counters::add(const Counters& other) {
  for (const auto& [pass, counters] : other.passes_)
    for (const auto& [name, value] : counters) add(pass, name, value);
}

std::uint64_t Counters::get(const std::string& pass, const std::string& name) const {
  const auto p = passes_.find(pass);
  if (p == passes_.end()) return 0;
  const auto c = p->second.find(name);
  return c == p->second.end() ? 0 : c->second;
}

std::uint64_t Counters::total(const std::string& name) const {
  std::uint64_t sum = 0;
  for (const auto& [pass, counters] : passes_) {
    const auto c = counters.find(name);
    if (c != counters.end()) sum += c->second;
  }
  return sum;
}

std::vector<std::string> counter_differences(const Counters& a, const Counters& b) {
  std::vector<std::string> out;
  // Walk the union of pass/name keys of both sides.
  std::map<std::string, std::map<std::string, int>> keys;
  for (const auto& [pass, counters] : a.passes())
    for (const auto& [name, value] : counters) keys[pass][name] |= 1;
  for (const auto& [pass, counters] : b.passes())
    for (const auto& [name, value] : counters) keys[pass][name] |= 2;
  for (const auto& [pass, names] : keys) {
    for (const auto& [name, sides] : names) {
      const std::string key = pass + "/" + name;
      if (sides == 1) {
        out.push_back(key + ": missing on the right");
      } else if (sides == 2) {
        out.push_back(key + ": missing on the left");
      } else {
        const std::uint64_t va = a.passes().at(pass).at(name);
        const std::uint64_t vb = b.passes().at(pass).at(name);
        if (va != vb) out.push_back(key + ": " + std::to_string(va) + " != " + std::to_string(vb));
      }
    }
  }
  return out;
}

}  // namespace hp
