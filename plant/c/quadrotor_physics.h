/* Quadrotor rigid-body physics: no FMI here, so it can be tested, benchmarked and reused on its own.
 *
 * Conventions (docs/design.md §3): world NED, body FRD, SI units, quaternions scalar first (w, x, y, z),
 * Euler ZYX. The structs qr_inputs, qr_params and qr_outputs are generated from plant/variables.py.
 */
#ifndef QUADROTOR_PHYSICS_H
#define QUADROTOR_PHYSICS_H

#include "quadrotor_vars.h"

/* Flat state vector, integrated by RK4. */
enum {
    QR_PN = 0,      /* position NED [3] */
    QR_VN = 3,      /* velocity NED [3] */
    QR_QW = 6,      /* attitude quaternion body->world [4] */
    QR_P = 10,      /* body rates [3] */
    QR_OMEGA = 13,  /* rotor speeds [4] */
    QR_GIMBAL = 17, /* single-axis stand: angle from the initial attitude, and its rate */
    QR_NSTATE = 19
};

enum { QR_STAND_FREE = 0, QR_STAND_ROLL = 1, QR_STAND_PITCH = 2, QR_STAND_YAW = 3, QR_STAND_ATTITUDE = 4 };

typedef struct {
    double y[QR_NSTATE];
    int on_ground; /* resting on the ground: held still until thrust lifts it */
} qr_state;

/* Checks parameters that would make the physics meaningless. Returns NULL when they are usable,
 * otherwise a static message naming the parameter and what it must be. */
const char *qr_check_params(const qr_params *par);

/* The initial state: at (pn0, pe0, pd0) with attitude (roll0, pitch0, yaw0), at rest, rotors already
 * at the steady speed their current ESC inputs command (so a vehicle started in the air at hover
 * pulse widths hovers from t = 0). */
void qr_init_state(const qr_params *par, const qr_inputs *in, qr_state *s);

/* Rotor speed the ESC commands for a pulse width: pulse widths are clamped into
 * [esc_min_us, esc_max_us] (as an ESC saturates); non-finite ones count as esc_min_us. Below
 * esc_start_us the ESC does not start the motor: the command is 0. */
double qr_esc_omega_cmd(const qr_params *par, int motor, double pwm_us);

/* Advances the state by dt (> 0) with RK4 sub-steps no longer than h_max_step; inputs are held
 * constant over dt. Returns 0, or -1 if the result was not finite (then *s is unchanged). */
int qr_advance(const qr_params *par, const qr_inputs *in, qr_state *s, double dt);

/* Fills every output from the state. */
void qr_outputs_from(const qr_params *par, const qr_inputs *in, const qr_state *s, qr_outputs *out);

/* ISA troposphere referenced to the ground: pressure (Pa) and temperature (degC) at height h (m)
 * above pd = 0. */
double qr_isa_pressure(const qr_params *par, double h);
double qr_isa_temperature(const qr_params *par, double h);

#endif
