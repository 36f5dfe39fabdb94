#pragma once
// Internal: scratch storage for the vectorised kernels (mean-value, Green). Not public API.

#include <cstddef>
#include <new>

namespace spacewarp::detail {

/// A 64-byte aligned scratch array of trivially copyable T. reserve() only grows and does not
/// keep the old contents: it is for per-thread scratch that is refilled on every use.
template <class T>
class AlignedBuffer {
 public:
  AlignedBuffer() = default;
  AlignedBuffer(const AlignedBuffer&) = delete;
  AlignedBuffer& operator=(const AlignedBuffer&) = delete;
  ~AlignedBuffer() { ::operator delete (data_, std::align_val_t{64}); }

  void reserve(std::size_t n) {
    if (n <= size_) return;
    ::operator delete (data_, std::align_val_t{64});
    data_ = static_cast<T*>(::operator new (n * sizeof(T), std::align_val_t{64}));
    size_ = n;
  }
  T* data() { return data_; }
  const T* data() const { return data_; }
  T& operator[](std::size_t i) { return data_[i]; }
  const T& operator[](std::size_t i) const { return data_[i]; }

 private:
  T* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace spacewarp::detail
