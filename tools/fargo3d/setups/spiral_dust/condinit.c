/* spiralbayes setup 'spiral_dust' (issue 21): initial conditions of a 2-D polar gas + dust disc.
 *
 * Gas: Sigma = SIGMA0 (r/R0)^-SIGMASLOPE, c_s = h(r) Omega_K r with h = ASPECTRATIO (r/R0)^FLARINGINDEX,
 * azimuthal velocity in radial equilibrium with the pressure gradient, no radial velocity.
 * Dust (fluid "dust1", pressureless): Sigma_d = EPSILON Sigma, Keplerian velocity; drag at the
 * Stokes number 1/INVSTOKES1 with feedback on the gas (FARGO3D's ColRate).
 */
#include "fargo3d.h"

static void fill(int is_gas) {
  int i, j, k;
  real r, omega, h, cs;
  real *rho = Density->field_cpu;
  real *cs_f = Energy->field_cpu;
  real *vphi = Vx->field_cpu;
  real *vr = Vy->field_cpu;

  k = 0;
  for (j = 0; j < Ny + 2 * NGHY; j++) {
    r = Ymed(j);
    omega = sqrt(G * MSTAR / (r * r * r));
    h = ASPECTRATIO * pow(r / R0, FLARINGINDEX);
    cs = h * omega * r;
    for (i = 0; i < Nx + 2 * NGHX; i++) {
      rho[l] = SIGMA0 * pow(r / R0, -SIGMASLOPE) * (is_gas ? 1.0 : EPSILON);
      cs_f[l] = is_gas ? cs : 0.0;
      vphi[l] = omega * r * (is_gas ? sqrt(1.0 + h * h * (2.0 * FLARINGINDEX - 1.0 - SIGMASLOPE)) : 1.0)
                - OMEGAFRAME * r;
      vr[l] = 0.0;
    }
  }
}

void CondInit() {
  Fluids[0] = CreateFluid("gas", GAS);
  SelectFluid(0);
  fill(1);
  Fluids[1] = CreateFluid("dust1", DUST);
  SelectFluid(1);
  fill(0);
  ColRate(INVSTOKES1, 0, 1, YES);   /* feedback on */
}
