// A per-thread ceiling on the memory operator new hands out while a scope is active.
//
// Draco 1.5.5 sizes its tables (corner tables, points, attribute values) from the counts
// a payload declares, before it finds the data missing; CheckDracoDeclaredCounts refuses
// the counts it can read from the header, and this is the backstop for those it cannot
// (attribute components, metadata): decoding untrusted bytes inside a scope makes an
// allocation beyond the scope's budget throw std::bad_alloc, which the decoder turns into
// INVALID_ARGUMENT, instead of taking the process's memory.
//
// The budget counts bytes requested (not freed) by operator new on this thread while the
// scope lives: a conservative, cheap measure (a thread-local check per allocation; no
// cost outside a scope). malloc called directly is not counted. Scopes nest: what an inner
// scope admits counts against every scope around it, and passing any of their budgets
// fails the allocation. A scope belongs to the thread that made it and must end on it,
// innermost first (as a local variable does).
#ifndef MLCLUST_CORE_IO_ALLOCATION_BUDGET_H_
#define MLCLUST_CORE_IO_ALLOCATION_BUDGET_H_

#include <cstddef>

namespace mlclust {

class ScopedAllocationBudget {
 public:
  explicit ScopedAllocationBudget(size_t budget_bytes);
  ~ScopedAllocationBudget();
  ScopedAllocationBudget(const ScopedAllocationBudget&) = delete;
  ScopedAllocationBudget& operator=(const ScopedAllocationBudget&) = delete;

  // Bytes operator new handed out on this thread since the scope began.
  size_t allocated_bytes() const;
  // Whether an allocation was refused because it would have passed the budget.
  bool exceeded() const;

 private:
  void* budget_;  // this scope's count, linked to the scope around it
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_IO_ALLOCATION_BUDGET_H_
