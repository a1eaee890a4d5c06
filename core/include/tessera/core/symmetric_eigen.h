// Eigenvectors of small symmetric matrices: the normal of a point neighbourhood is the
// eigenvector of its covariance's smallest eigenvalue (principal component analysis, Hoppe et
// al. 1992). Used by the surface pick (interact/) and the range maps' normals (lod/).
// Header-only, no state, any thread.
#pragma once

#include <cmath>

#include <glm/glm.hpp>

namespace tessera {

/// The unit eigenvector of the smallest eigenvalue of a symmetric 3x3 matrix, by cyclic Jacobi
/// rotations (Golub and Van Loan, 8.5) until the off-diagonal part is 1e-30 of the diagonal,
/// at most 32 sweeps. The sign is whatever the rotations leave; callers orient it. A matrix
/// with a repeated smallest eigenvalue returns one unit vector of that eigenspace. NaN in, NaN
/// out.
inline glm::dvec3 smallestEigenvector(glm::dmat3 a) {
  glm::dmat3 v(1.0);
  for (int sweep = 0; sweep < 32; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    if (off < 1e-30 * (a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2]) || off == 0.0)
      break;
    for (int p = 0; p < 2; ++p) {
      for (int q = p + 1; q < 3; ++q) {
        if (a[p][q] == 0.0) continue;
        const double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
        const double t =
            (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1.0));
        const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
        glm::dmat3 r(1.0);
        r[p][p] = c;
        r[q][q] = c;
        r[q][p] = s;  // glm: r[column][row]
        r[p][q] = -s;
        a = glm::transpose(r) * a * r;
        v = v * r;
      }
    }
  }
  int k = 0;
  for (int i = 1; i < 3; ++i)
    if (a[i][i] < a[k][k]) k = i;
  return glm::normalize(v[k]);
}

}  // namespace tessera
