// An allocator whose value-initialising construct() default-initialises instead, so that
// std::vector::resize of a trivially default-constructible type leaves the new elements as they are (no
// zero-fill pass): for large scratch buffers that are written before they are read.
#pragma once

#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace duplexfit::detail {

template <typename T, typename Base = std::allocator<T>>
class DefaultInitAllocator : public Base {
  using Traits = std::allocator_traits<Base>;

 public:
  template <typename U>
  struct rebind {
    using other = DefaultInitAllocator<U, typename Traits::template rebind_alloc<U>>;
  };

  using Base::Base;
  DefaultInitAllocator() = default;
  template <typename U, typename B>
  DefaultInitAllocator(const DefaultInitAllocator<U, B>& other) noexcept : Base(other) {}

  /// construct(p) with no arguments: default-initialisation (nothing for a trivial type).
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    Traits::construct(static_cast<Base&>(*this), p, std::forward<Args>(args)...);
  }
};

/// A vector whose resize does not zero-fill trivial elements.
template <typename T>
using ScratchVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace duplexfit::detail
