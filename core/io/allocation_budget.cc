#include "core/io/allocation_budget.h"

#include <cstdlib>
#include <new>

namespace mlclust {
namespace {

struct Budget {
  size_t limit = 0;
  size_t allocated = 0;
  bool exceeded = false;
  Budget* outer = nullptr;  // the scope this one is nested in
};

thread_local Budget* active_budget = nullptr;

// Counts `size` against the active scope and every scope it is nested in; false (and
// nothing counted) where it would pass any of their budgets.
bool Admit(size_t size) {
  Budget* innermost = active_budget;
  if (innermost == nullptr) return true;
  for (Budget* budget = innermost; budget != nullptr; budget = budget->outer) {
    if (size > budget->limit - budget->allocated) {
      budget->exceeded = true;
      return false;
    }
  }
  for (Budget* budget = innermost; budget != nullptr; budget = budget->outer) {
    budget->allocated += size;
  }
  return true;
}

// operator new's contract: the new-handler loop where malloc fails; std::bad_alloc at
// once where the budget refuses.
void* AllocateOrThrow(size_t size, size_t alignment) {
  if (!Admit(size)) throw std::bad_alloc();
  for (;;) {
    void* p = nullptr;
    if (alignment == 0) {
      p = std::malloc(size == 0 ? 1 : size);
    } else {
      // aligned_alloc wants a size that is a multiple of the alignment.
      p = std::aligned_alloc(alignment,
                             ((size == 0 ? 1 : size) + alignment - 1) / alignment * alignment);
    }
    if (p != nullptr) return p;
    std::new_handler handler = std::get_new_handler();
    if (handler == nullptr) throw std::bad_alloc();
    handler();
  }
}

void* AllocateOrNull(size_t size, size_t alignment) noexcept {
  try {
    return AllocateOrThrow(size, alignment);
  } catch (const std::bad_alloc&) {
    return nullptr;
  }
}

}  // namespace

ScopedAllocationBudget::ScopedAllocationBudget(size_t budget_bytes) {
  // Counted against the scopes this one is nested in (a few bytes), not against itself.
  budget_ = new Budget{budget_bytes, 0, false, active_budget};
  active_budget = static_cast<Budget*>(budget_);
}

ScopedAllocationBudget::~ScopedAllocationBudget() {
  Budget* budget = static_cast<Budget*>(budget_);
  active_budget = budget->outer;
  delete budget;
}

size_t ScopedAllocationBudget::allocated_bytes() const {
  return static_cast<const Budget*>(budget_)->allocated;
}

bool ScopedAllocationBudget::exceeded() const {
  return static_cast<const Budget*>(budget_)->exceeded;
}

}  // namespace mlclust

// The replaceable allocation functions ([new.delete]), with their deallocation functions
// below. Only the throwing and nothrow forms count: placement new is not replaceable and
// allocates nothing.
void* operator new(size_t size) { return mlclust::AllocateOrThrow(size, 0); }
void* operator new[](size_t size) { return mlclust::AllocateOrThrow(size, 0); }
void* operator new(size_t size, const std::nothrow_t& /*tag*/) noexcept {
  return mlclust::AllocateOrNull(size, 0);
}
void* operator new[](size_t size, const std::nothrow_t& /*tag*/) noexcept {
  return mlclust::AllocateOrNull(size, 0);
}
void* operator new(size_t size, std::align_val_t alignment) {
  return mlclust::AllocateOrThrow(size, static_cast<size_t>(alignment));
}
void* operator new[](size_t size, std::align_val_t alignment) {
  return mlclust::AllocateOrThrow(size, static_cast<size_t>(alignment));
}
void* operator new(size_t size, std::align_val_t alignment,
                   const std::nothrow_t& /*tag*/) noexcept {
  return mlclust::AllocateOrNull(size, static_cast<size_t>(alignment));
}
void* operator new[](size_t size, std::align_val_t alignment,
                     const std::nothrow_t& /*tag*/) noexcept {
  return mlclust::AllocateOrNull(size, static_cast<size_t>(alignment));
}

// The matching deallocation functions: memory from the functions above is malloc's, so it
// goes back to free (the default ones do the same, but sanitizers pair new with delete and
// would report malloc's memory reaching their operator delete).
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t /*size*/) noexcept { std::free(p); }
void operator delete[](void* p, size_t /*size*/) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t& /*tag*/) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t& /*tag*/) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t /*alignment*/) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t /*alignment*/) noexcept { std::free(p); }
void operator delete(void* p, size_t /*size*/, std::align_val_t /*alignment*/) noexcept {
  std::free(p);
}
void operator delete[](void* p, size_t /*size*/, std::align_val_t /*alignment*/) noexcept {
  std::free(p);
}
void operator delete(void* p, std::align_val_t /*alignment*/,
                     const std::nothrow_t& /*tag*/) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::align_val_t /*alignment*/,
                       const std::nothrow_t& /*tag*/) noexcept {
  std::free(p);
}
