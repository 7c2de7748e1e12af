// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Result<T> for start-up code (opening devices, loading scenes): a value or an error message
/// meant for a person. g++ 12 in C++20 mode has no std::expected; this is the small part of it
/// we use. Never used on the hot path (its error holds a std::string).

#include <optional>
#include <string>
#include <utility>

namespace toonforce {

struct Error {
  std::string message;
};

template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}              // NOLINT(google-explicit-constructor)
  Result(Error error) : error_(std::move(error.message)) {}  // NOLINT(google-explicit-constructor)

  explicit operator bool() const noexcept { return value_.has_value(); }
  bool ok() const noexcept { return value_.has_value(); }
  T& value() & { return *value_; }
  const T& value() const& { return *value_; }
  T&& value() && { return std::move(*value_); }
  T* operator->() { return &*value_; }
  const T* operator->() const { return &*value_; }
  const std::string& error() const noexcept { return error_; }

 private:
  std::optional<T> value_;
  std::string error_;
};

}  // namespace toonforce
