#pragma once
/// \file error.hpp
/// The one exception family of sdot. Exceptions are only thrown for invalid input;
/// non-convergence and other expected outcomes are reported through `sdot::Summary`.

#include <stdexcept>
#include <string>

namespace sdot {

/// Base of every exception sdot throws.
class Error : public std::runtime_error {
 public:
  /// std::runtime_error's constructors: the message is what() returns.
  using std::runtime_error::runtime_error;
};

/// Invalid input. The message names the offending field (and index when there is one),
/// e.g. `sites[3]: duplicate of sites[1]` or `domain: polygon is not convex at vertex 2`.
class InputError : public Error {
 public:
  /// \param field  what is wrong, as a path into the input (`sites[3]`, `options.tolerance`).
  /// \param problem  what is wrong with it.
  InputError(const std::string& field, const std::string& problem) : Error(field + ": " + problem), field_(field) {}
  /// The field (with index) that is wrong.
  [[nodiscard]] const std::string& field() const noexcept { return field_; }

 private:
  std::string field_;
};

/// Indexed field name, e.g. `indexed("sites", 3)` is `"sites[3]"`.
inline std::string indexed(const std::string& field, std::size_t index) {
  return field + "[" + std::to_string(index) + "]";
}

}  // namespace sdot
