/* spiralbayes setup 'spiral_beta' (issue 21): beta cooling as a source step.
 *
 * FARGO3D calls SetupHook1() at the start of Sources(dt) in every time step (src/algogas.c), before
 * the pressure is computed.  The hook relaxes the internal energy per unit area e towards
 * e_eq = Sigma c_s0(r)^2/(GAMMA - 1), the initial (unperturbed) temperature profile at the current
 * surface density, on the cooling time tau_c = BETACOOL/Omega_K(r), with the implicit update
 *     e <- (e + (dt/tau_c) e_eq)/(1 + dt/tau_c)
 * (unconditionally stable; exact decay rate 1/tau_c for dt << tau_c).  The hook has no dt argument:
 * dt is the physical time elapsed since its previous call (the previous step), so the relaxation is
 * applied one step late, which is first-order operator splitting like FARGO3D's own source steps.
 * BETACOOL <= 0 switches cooling off (adiabatic).  CPU builds only (no SetupHook1_gpu here).
 */
#include "fargo3d.h"

void SetupHook1_cpu() {
  static int started = 0;
  static real t_last = 0.0;
  int i, j, k;
  real dt, r, omega, h, cs2, a, e_eq;
  real *rho, *e;

  if (Fluidtype != GAS) return;
  if (!started) {
    started = 1;
    t_last = PhysicalTime;
    return;
  }
  dt = PhysicalTime - t_last;
  t_last = PhysicalTime;
  if (BETACOOL <= 0.0 || dt <= 0.0) return;

  INPUT(Density);
  INPUT(Energy);
  OUTPUT(Energy);
  rho = Density->field_cpu;
  e = Energy->field_cpu;
  k = 0;
  for (j = 0; j < Ny + 2 * NGHY; j++) {
    r = Ymed(j);
    omega = sqrt(G * MSTAR / (r * r * r));
    h = ASPECTRATIO * pow(r / R0, FLARINGINDEX);
    cs2 = h * h * omega * omega * r * r;
    a = dt * omega / BETACOOL;                      /* dt/tau_c */
    for (i = 0; i < Nx + 2 * NGHX; i++) {
      e_eq = rho[l] * cs2 / (GAMMA - 1.0);
      e[l] = (e[l] + a * e_eq) / (1.0 + a);
    }
  }
}
