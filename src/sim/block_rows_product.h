// Internal to sim_core: the product of a matrix stored as rows of b x b blocks (compressed block rows)
// with a vector, shared by BlockSparseMatrix::multiply and the two-level preconditioner's A P.
#pragma once

#include <vector>

#include "textile_handling/sim/types.h"

namespace textile_handling {

/// y = M x. M has row_start.size() - 1 block rows; the blocks of row i are k = row_start[i] ..
/// row_start[i + 1] - 1, block k at block column col[k] with its b x b values row-major at
/// values[k * b * b]. x has (largest column + 1) * b entries, y is resized to rows * b (an empty row
/// gives zeros). Rows run in parallel when worth it, each summed in block order: bitwise the same for
/// any thread count.
void multiplyBlockRows(const std::vector<Index>& row_start, const std::vector<Index>& col,
                       const std::vector<Real>& values, int b, const VecX& x, VecX& y);

}  // namespace textile_handling
