// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Eigenvalues of small dense real matrices, for the stability maps' linear analysis: the
/// transition matrix of a sampled loop is stable (every disturbance decays) if and only if its
/// spectral radius, the largest |eigenvalue|, is below 1 (any linear-systems text, e.g.
/// Franklin, Powell and Workman, "Digital Control of Dynamic Systems", 3rd ed., §4.3).
///
/// Method: balancing (Parlett and Reinsch 1969), reduction to upper Hessenberg form by
/// Gaussian elimination with pivoting, then Francis double-shift QR iteration: EISPACK's
/// balanc, elmhes and hqr as given in Numerical Recipes, 3rd ed., §11.6-11.7. Backward stable:
/// each computed eigenvalue is an exact one of a matrix within a few ulps of the balanced
/// input, so a simple eigenvalue is accurate to about eps times its condition number (ample
/// for the 4-12 state loops here, whose eigenvalues are simple and well separated).
#include <complex>
#include <vector>

#include "toonforce/common/result.hpp"

namespace toonforce::report {

/// A square matrix, row-major: m[row][column].
using Matrix = std::vector<std::vector<double>>;

/// All eigenvalues of `a` (n x n, n >= 1), complex pairs as conjugates, in no set order. Fails
/// (never for the matrices the report builds) if the QR iteration does not converge in 60
/// iterations for some eigenvalue, or `a` is not square or not finite.
Result<std::vector<std::complex<double>>> eigenvalues(Matrix a);

/// max |eigenvalue| of `a`.
Result<double> spectral_radius(const Matrix& a);

}  // namespace toonforce::report
