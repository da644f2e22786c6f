// Sets an environment variable for one scope and puts back what was there (or its absence) at the end, also
// when a fatal assertion leaves the test early: the rest of the process (lavapipe included) reads it too.
#pragma once

#include <cstdlib>
#include <optional>
#include <string>

namespace hp::test {

class ScopedEnv {
 public:
  explicit ScopedEnv(const char* name) : name_(name) {
    if (const char* v = std::getenv(name)) saved_ = v;
  }
  ~ScopedEnv() {
    if (saved_) {
      setenv(name_, saved_->c_str(), 1);
    } else {
      unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;
  /// Returns setenv's result (0 on success).
  int set(const char* value) const { return setenv(name_, value, 1); }
  /// Returns unsetenv's result (0 on success).
  int unset() const { return unsetenv(name_); }

 private:
  const char* name_;
  std::optional<std::string> saved_;
};

}  // namespace hp::test
