/* spiralbayes setup 'spiral_beta' (issue 21): initial conditions of a 2-D polar, adiabatic disc.
 *
 * Sigma = SIGMA0 (r/R0)^-SIGMASLOPE, c_s = h(r) Omega_K r with h = ASPECTRATIO (r/R0)^FLARINGINDEX,
 * internal energy per unit area e = (1 + EPERT) Sigma c_s^2/(GAMMA - 1) (EPERT = 0 for the planet
 * runs; EPERT != 0 gives the thermal-relaxation test its initial temperature excess), azimuthal
 * velocity in radial equilibrium with the unperturbed pressure, no radial velocity.
 * The unperturbed temperature profile is also the relaxation target of setuphook1.c.
 */
#include "fargo3d.h"

void CondInit() {
  int i, j, k;
  real r, omega, cs, h;
  real *rho, *e, *vphi, *vr;

  Fluids[0] = CreateFluid("gas", GAS);
  SelectFluid(0);
  OUTPUT(Density);
  OUTPUT(Energy);
  OUTPUT(Vx);
  OUTPUT(Vy);
  rho = Density->field_cpu;
  e = Energy->field_cpu;
  vphi = Vx->field_cpu;
  vr = Vy->field_cpu;

  k = 0;
  for (j = 0; j < Ny + 2 * NGHY; j++) {
    r = Ymed(j);
    omega = sqrt(G * MSTAR / (r * r * r));
    h = ASPECTRATIO * pow(r / R0, FLARINGINDEX);
    cs = h * omega * r;
    for (i = 0; i < Nx + 2 * NGHX; i++) {
      rho[l] = SIGMA0 * pow(r / R0, -SIGMASLOPE);
      e[l] = (1.0 + EPERT) * rho[l] * cs * cs / (GAMMA - 1.0);
      /* Omega^2 r = GM/r^2 + (1/Sigma) dP/dr with P = Sigma c_s^2 (power laws) */
      vphi[l] = omega * r * sqrt(1.0 + h * h * (2.0 * FLARINGINDEX - 1.0 - SIGMASLOPE)) - OMEGAFRAME * r;
      vr[l] = 0.0;
    }
  }
}
