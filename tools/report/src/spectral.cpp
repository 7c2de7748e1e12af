// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/spectral.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

#include <fmt/format.h>

namespace toonforce::report {

namespace {

using Index = std::ptrdiff_t;

double& at(Matrix& a, Index i, Index j) { return a[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)]; }

double sign_of(double magnitude, double sign) { return sign >= 0.0 ? std::fabs(magnitude) : -std::fabs(magnitude); }

/// Scales rows and columns by powers of 2 (exact) so that each row and column have similar
/// norms: a similarity, so the eigenvalues are unchanged, but the QR iteration's round-off,
/// which scales with the matrix norm, shrinks (Numerical Recipes 3rd ed. §11.6, balanc).
void balance(Matrix& a, Index n) {
  constexpr double kRadix = 2.0;
  constexpr double kRadix2 = kRadix * kRadix;
  bool done = false;
  while (!done) {
    done = true;
    for (Index i = 0; i < n; ++i) {
      double r = 0.0;
      double c = 0.0;
      for (Index j = 0; j < n; ++j) {
        if (j == i) continue;
        c += std::fabs(at(a, j, i));
        r += std::fabs(at(a, i, j));
      }
      if (c == 0.0 || r == 0.0) continue;
      double g = r / kRadix;
      double f = 1.0;
      const double s = c + r;
      while (c < g) {
        f *= kRadix;
        c *= kRadix2;
      }
      g = r * kRadix;
      while (c > g) {
        f /= kRadix;
        c /= kRadix2;
      }
      if ((c + r) / f < 0.95 * s) {
        done = false;
        g = 1.0 / f;
        for (Index j = 0; j < n; ++j) at(a, i, j) *= g;
        for (Index j = 0; j < n; ++j) at(a, j, i) *= f;
      }
    }
  }
}

/// Upper Hessenberg form by stabilised elementary similarity transforms (elmhes).
void hessenberg(Matrix& a, Index n) {
  for (Index m = 1; m < n - 1; ++m) {
    double x = 0.0;
    Index pivot = m;
    for (Index j = m; j < n; ++j) {
      if (std::fabs(at(a, j, m - 1)) > std::fabs(x)) {
        x = at(a, j, m - 1);
        pivot = j;
      }
    }
    if (pivot != m) {
      for (Index j = m - 1; j < n; ++j) std::swap(at(a, pivot, j), at(a, m, j));
      for (Index j = 0; j < n; ++j) std::swap(at(a, j, pivot), at(a, j, m));
    }
    if (x == 0.0) continue;
    for (Index i = m + 1; i < n; ++i) {
      double y = at(a, i, m - 1);
      if (y == 0.0) continue;
      y /= x;
      at(a, i, m - 1) = 0.0;
      for (Index j = m; j < n; ++j) at(a, i, j) -= y * at(a, m, j);
      for (Index j = 0; j < n; ++j) at(a, j, m) += y * at(a, j, i);
    }
  }
  for (Index i = 2; i < n; ++i) {
    for (Index j = 0; j < i - 1; ++j) at(a, i, j) = 0.0;
  }
}

/// Eigenvalues of an upper Hessenberg matrix by the Francis double-shift QR iteration (hqr),
/// with the exceptional shifts of EISPACK after 10 and 20 iterations without deflation.
bool hqr(Matrix& a, Index n, std::vector<std::complex<double>>& out) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  out.assign(static_cast<std::size_t>(n), {});
  const auto put = [&out](Index i, std::complex<double> z) { out[static_cast<std::size_t>(i)] = z; };
  double anorm = 0.0;
  for (Index i = 0; i < n; ++i) {
    for (Index j = std::max<Index>(i - 1, 0); j < n; ++j) anorm += std::fabs(at(a, i, j));
  }
  Index nn = n - 1;
  double t = 0.0;
  double p = 0.0;
  double q = 0.0;
  double r = 0.0;
  double s = 0.0;
  double w = 0.0;
  double x = 0.0;
  double y = 0.0;
  double z = 0.0;
  while (nn >= 0) {
    int its = 0;
    Index l = 0;
    do {
      for (l = nn; l > 0; --l) {
        s = std::fabs(at(a, l - 1, l - 1)) + std::fabs(at(a, l, l));
        if (s == 0.0) s = anorm;
        if (std::fabs(at(a, l, l - 1)) <= kEps * s) {
          at(a, l, l - 1) = 0.0;
          break;
        }
      }
      x = at(a, nn, nn);
      if (l == nn) {  // one root found
        put(nn, x + t);
        --nn;
      } else {
        y = at(a, nn - 1, nn - 1);
        w = at(a, nn, nn - 1) * at(a, nn - 1, nn);
        if (l == nn - 1) {  // two roots found
          p = 0.5 * (y - x);
          q = p * p + w;
          z = std::sqrt(std::fabs(q));
          x += t;
          if (q >= 0.0) {
            z = p + sign_of(z, p);
            put(nn - 1, x + z);
            put(nn, x + z);
            if (z != 0.0) put(nn, x - w / z);
          } else {
            put(nn, {x + p, -z});
            put(nn - 1, {x + p, z});
          }
          nn -= 2;
        } else {
          if (its == 60) return false;
          if (its == 10 || its == 20) {  // exceptional shift
            t += x;
            for (Index i = 0; i <= nn; ++i) at(a, i, i) -= x;
            s = std::fabs(at(a, nn, nn - 1)) + std::fabs(at(a, nn - 1, nn - 2));
            y = x = 0.75 * s;
            w = -0.4375 * s * s;
          }
          ++its;
          Index m = nn - 2;
          for (; m >= l; --m) {
            z = at(a, m, m);
            r = x - z;
            s = y - z;
            p = (r * s - w) / at(a, m + 1, m) + at(a, m, m + 1);
            q = at(a, m + 1, m + 1) - z - r - s;
            r = at(a, m + 2, m + 1);
            s = std::fabs(p) + std::fabs(q) + std::fabs(r);
            p /= s;
            q /= s;
            r /= s;
            if (m == l) break;
            const double u = std::fabs(at(a, m, m - 1)) * (std::fabs(q) + std::fabs(r));
            const double v =
                std::fabs(p) * (std::fabs(at(a, m - 1, m - 1)) + std::fabs(z) + std::fabs(at(a, m + 1, m + 1)));
            if (u <= kEps * v) break;
          }
          for (Index i = m; i < nn - 1; ++i) {
            at(a, i + 2, i) = 0.0;
            if (i != m) at(a, i + 2, i - 1) = 0.0;
          }
          for (Index k = m; k < nn; ++k) {
            if (k != m) {
              p = at(a, k, k - 1);
              q = at(a, k + 1, k - 1);
              r = 0.0;
              if (k + 1 != nn) r = at(a, k + 2, k - 1);
              if ((x = std::fabs(p) + std::fabs(q) + std::fabs(r)) != 0.0) {
                p /= x;
                q /= x;
                r /= x;
              }
            }
            if ((s = sign_of(std::sqrt(p * p + q * q + r * r), p)) != 0.0) {
              if (k == m) {
                if (l != m) at(a, k, k - 1) = -at(a, k, k - 1);
              } else {
                at(a, k, k - 1) = -s * x;
              }
              p += s;
              x = p / s;
              y = q / s;
              z = r / s;
              q /= p;
              r /= p;
              for (Index j = k; j <= nn; ++j) {
                p = at(a, k, j) + q * at(a, k + 1, j);
                if (k + 1 != nn) {
                  p += r * at(a, k + 2, j);
                  at(a, k + 2, j) -= p * z;
                }
                at(a, k + 1, j) -= p * y;
                at(a, k, j) -= p * x;
              }
              const Index mmin = nn < k + 3 ? nn : k + 3;
              for (Index i = l; i <= mmin; ++i) {
                p = x * at(a, i, k) + y * at(a, i, k + 1);
                if (k + 1 != nn) {
                  p += z * at(a, i, k + 2);
                  at(a, i, k + 2) -= p * r;
                }
                at(a, i, k + 1) -= p * q;
                at(a, i, k) -= p;
              }
            }
          }
        }
      }
    } while (l + 1 < nn);
  }
  return true;
}

}  // namespace

Result<std::vector<std::complex<double>>> eigenvalues(Matrix a) {
  const auto n = static_cast<Index>(a.size());
  if (n == 0) return Error{"eigenvalues: an empty matrix"};
  for (const auto& row : a) {
    if (static_cast<Index>(row.size()) != n) return Error{"eigenvalues: the matrix is not square"};
    for (const double e : row) {
      if (!std::isfinite(e)) return Error{"eigenvalues: the matrix is not finite"};
    }
  }
  balance(a, n);
  hessenberg(a, n);
  std::vector<std::complex<double>> out;
  if (!hqr(a, n, out)) return Error{fmt::format("eigenvalues: the QR iteration did not converge ({} x {})", n, n)};
  return out;
}

Result<double> spectral_radius(const Matrix& a) {
  auto values = eigenvalues(a);
  if (!values) return Error{values.error()};
  double rho = 0.0;
  for (const auto& z : values.value()) rho = std::max(rho, std::abs(z));
  return rho;
}

}  // namespace toonforce::report
