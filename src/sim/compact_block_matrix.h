// Internal to sim_core: a copy of a block-sparse matrix's values laid out for fast products, for the
// iterative solvers, which multiply by the same system matrix two or three times per iteration.
//
// Why: with 5 DOFs per node (position, then the two material coordinates u and v of a yarn crossing)
// most blocks have whole rows and columns of zeros. A block between two nodes of one warp yarn couples
// only (x, u), one along a weft yarn only (x, v), a diagonal neighbour (shear) only x. The product
// reads every stored value once and is limited by memory bandwidth, so storing each block as the
// smallest square DOF subset that holds its nonzeros reads about 40 % less on a yarn sheet.
#pragma once

#include <cstdint>
#include <vector>

#include "textile_handling/sim/block_sparse.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

class CompactBlockMatrix {
 public:
  /// Copies the values of `a` (its pattern is kept by pointer and must outlive this copy). For block
  /// size 5 each block is stored as the first DOF subset of {x}, {x, u}, {x, v}, {x, u, v} (DOFs
  /// {0,1,2}, {0..3}, {0,1,2,4}, all) that covers its nonzero rows and columns; for other block sizes
  /// nothing is copied and multiply() uses `a`. The subsets are chosen from the values on the first
  /// call for a pattern and only ever widened: a later call that finds a nonzero outside a block's
  /// subset (NaN counts as nonzero) widens that block's subset and repacks.
  void assign(const BlockSparseMatrix& a);
  /// y = A x with the values of the last assign() (x: nodes * b entries; y resized to the same). Rows
  /// run in parallel, each summed in block order: the same bits on any thread count. Terms dropped
  /// with a zero row or column of a block contribute exact zeros, so y equals the full product up to
  /// the rounding of the order within a block.
  void multiply(const VecX& x, VecX& y) const;
  /// Values stored (for tests and memory figures): the full matrix's count when not compacted.
  std::size_t storedValues() const;

 private:
  // One of the DOF subsets, by index into kSubsets (compact_block_matrix.cpp).
  using Subset = std::uint8_t;

  // True if subset_ holds one subset per block of a's pattern (kept from the last assign).
  bool compacts(const BlockSparseMatrix& a) const;
  void chooseSubsets(const BlockSparseMatrix& a);
  bool pack(const BlockSparseMatrix& a);  // false if a nonzero lies outside its block's subset

  const BlockSparseMatrix* full_ = nullptr;
  const BlockPattern* pattern_ = nullptr;
  std::vector<Subset> subset_;       // per block slot
  std::vector<std::uint32_t> start_;  // per block slot: offset of its values in values_; one more at the end
  std::vector<Real> values_;          // each block's subset rows x subset columns, row-major
};

}  // namespace textile_handling
