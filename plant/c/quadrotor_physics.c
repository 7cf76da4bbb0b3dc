/* Quadrotor rigid-body physics; see quadrotor_physics.h for the contract. */
#include "quadrotor_physics.h"

#include <math.h>
#include <string.h>

/* ISA constants (US Standard Atmosphere 1976): lapse rate, g0*M/(R*L) = 5.25588. */
#define ISA_LAPSE 0.0065
#define ISA_EXPONENT (9.80665 * 0.0289644 / (8.31432 * ISA_LAPSE))
#define KELVIN 273.15
#define QR_PI 3.14159265358979323846
/* The derivatives' chain, inlined into each of RK4's four stages: as calls they were about a fifth of
 * a flying step's instructions (argument arrays through memory, bench/run_instructions.py). Inlining
 * changes no arithmetic (no contraction, no reassociation: the same operations in the same order). */
#define INLINE static inline __attribute__((always_inline))

/* Rotor layout: angle of each arm from the nose towards the right wing, "+" frame; the X frame turns
 * every arm 45 degrees clockwise seen from above (a parameter set, not a second code path). Rotors 1
 * and 3 spin counter-clockwise seen from above, so their reaction torque on the body is nose-right
 * (+z in FRD); rotors 2 and 4 the opposite. */
static const double ARM_ANGLE[4] = { 0.0, -QR_PI / 2, QR_PI, QR_PI / 2 };
static const double SPIN_SIGN[4] = { 1.0, -1.0, 1.0, -1.0 };

typedef struct {
    const qr_params *par;
    const qr_inputs *in;
    double omega_cmd[4];
    double arm_x[4], arm_y[4];
    double health[4];
    int mode;       /* QR_STAND_* or -1 for "resting on the ground" */
    double axis[3]; /* single-axis stands: rotation axis in body axes */
    double axis_inertia;
} ctx_t;

static double clamp(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* The ranges of plant/variables.py (one table: the scenario checker applies the same rules, and
   modelDescription.xml declares the closed bounds), then the rules that relate two parameters. */
const char *qr_check_params(const qr_params *p)
{
#define QR_CHECK(field, low, low_open, high, high_open, message)              \
    {                                                                         \
        double v_ = (double)p->field;                                         \
        if (!isfinite(v_) || ((low_open) ? !(v_ > (low)) : !(v_ >= (low))) || \
            ((high_open) ? !(v_ < (high)) : !(v_ <= (high))))                 \
            return message;                                                   \
    }
    QR_PARAM_RANGES(QR_CHECK)
#undef QR_CHECK
    if (!(p->esc_max_us > p->esc_min_us))
        return "esc_max_us must be > esc_min_us";
    if (!(p->Ixx == QR_SEED_IXX && p->Iyy == QR_SEED_IYY && p->Izz == QR_SEED_IZZ)) {
        /* a rigid body's principal moments: each at most the sum of the other two (seed 001's
           Table 1 alone is exempt, see plant/variables.py) */
        if (p->Ixx > (p->Iyy + p->Izz) * (1 + QR_TRIANGLE_SLACK))
            return "Ixx must be <= Iyy + Izz (the triangle inequality of a rigid body's principal "
                   "moments of inertia)";
        if (p->Iyy > (p->Ixx + p->Izz) * (1 + QR_TRIANGLE_SLACK))
            return "Iyy must be <= Ixx + Izz (the triangle inequality of a rigid body's principal "
                   "moments of inertia)";
        if (p->Izz > (p->Ixx + p->Iyy) * (1 + QR_TRIANGLE_SLACK))
            return "Izz must be <= Ixx + Iyy (the triangle inequality of a rigid body's principal "
                   "moments of inertia)";
    }
    if (p->stand == QR_STAND_FREE && p->pd0 > 0)
        return "pd0 must be <= 0 in free flight (the ground is at pd = 0)";
    return NULL;
}

/* --- small vector helpers ------------------------------------------------------------------- */

static void quat_from_euler(double roll, double pitch, double yaw, double q[4])
{
    double cr = cos(roll / 2), sr = sin(roll / 2), cp = cos(pitch / 2), sp = sin(pitch / 2);
    double cy = cos(yaw / 2), sy = sin(yaw / 2);
    q[0] = cr * cp * cy + sr * sp * sy;
    q[1] = sr * cp * cy - cr * sp * sy;
    q[2] = cr * sp * cy + sr * cp * sy;
    q[3] = cr * cp * sy - sr * sp * cy;
}

static void quat_mul(const double a[4], const double b[4], double out[4])
{
    double w = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    double x = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    double y = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    double z = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
    out[0] = w;
    out[1] = x;
    out[2] = y;
    out[3] = z;
}

/* Rotation matrix body -> world from a unit quaternion. */
INLINE void quat_to_dcm(const double q[4], double R[3][3])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    R[0][0] = 1 - 2 * (y * y + z * z);
    R[0][1] = 2 * (x * y - w * z);
    R[0][2] = 2 * (x * z + w * y);
    R[1][0] = 2 * (x * y + w * z);
    R[1][1] = 1 - 2 * (x * x + z * z);
    R[1][2] = 2 * (y * z - w * x);
    R[2][0] = 2 * (x * z - w * y);
    R[2][1] = 2 * (y * z + w * x);
    R[2][2] = 1 - 2 * (x * x + y * y);
}

INLINE void mat_vec(double R[3][3], const double v[3], double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = R[i][0] * v[0] + R[i][1] * v[1] + R[i][2] * v[2];
}

static void mat_t_vec(double R[3][3], const double v[3], double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = R[0][i] * v[0] + R[1][i] * v[1] + R[2][i] * v[2];
}

static void quat_normalize(double *q)
{
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int i = 0; i < 4; i++)
        q[i] /= n;
}

/* --- model ---------------------------------------------------------------------------------- */

double qr_esc_omega_cmd(const qr_params *p, int i, double pwm_us)
{
    double pw = isfinite(pwm_us) ? clamp(pwm_us, p->esc_min_us, p->esc_max_us) : p->esc_min_us;
    if (pw < p->esc_start_us)
        return 0.0; /* below the ESC's start threshold the motor stands still */
    double u = (pw - p->esc_min_us) / (p->esc_max_us - p->esc_min_us);
    return p->omega_max * clamp(p->esc_gain[i] * u + p->esc_offset[i], 0.0, 1.0);
}

double qr_isa_pressure(const qr_params *p, double h)
{
    double t0 = p->t_ground + KELVIN;
    return p->p_ground * pow(1.0 - ISA_LAPSE * h / t0, ISA_EXPONENT);
}

double qr_isa_temperature(const qr_params *p, double h) { return p->t_ground - ISA_LAPSE * h; }

/* Body-axis force (thrust only) and torque (thrust moments, reaction torques, external torque). */
INLINE void rotor_loads(const ctx_t *c, const double *y, double force_b[3], double torque_b[3])
{
    const qr_params *p = c->par;
    force_b[0] = force_b[1] = force_b[2] = 0;
    torque_b[0] = c->in->tau_ext[0];
    torque_b[1] = c->in->tau_ext[1];
    torque_b[2] = c->in->tau_ext[2];
    for (int i = 0; i < 4; i++) {
        double w2 = y[QR_OMEGA + i] * y[QR_OMEGA + i] * c->health[i];
        double t = p->k_thrust * w2;
        force_b[2] -= t;
        torque_b[0] -= c->arm_y[i] * t; /* r x (0, 0, -t) */
        torque_b[1] += c->arm_x[i] * t;
        torque_b[2] += SPIN_SIGN[i] * p->k_torque * w2;
    }
}

/* World-frame acceleration of the free body (gravity, thrust, drag, external force). */
INLINE void free_accel(const ctx_t *c, const double *y, double R[3][3], const double force_b[3], double acc[3])
{
    const qr_params *p = c->par;
    double f_w[3];
    mat_vec(R, force_b, f_w);
    for (int k = 0; k < 3; k++) {
        double drag = -p->drag[k] * (y[QR_VN + k] - c->in->wind[k]);
        acc[k] = (f_w[k] + drag + c->in->f_ext[k]) / p->mass;
    }
    acc[2] += p->gravity;
}

INLINE void derivatives(const ctx_t *c, const double *y, double *dy)
{
    const qr_params *p = c->par;
    memset(dy, 0, sizeof(double) * QR_NSTATE);
    for (int i = 0; i < 4; i++)
        dy[QR_OMEGA + i] = (c->omega_cmd[i] - y[QR_OMEGA + i]) / p->motor_tau;

    double force_b[3], torque_b[3];
    rotor_loads(c, y, force_b, torque_b);

    if (c->mode == QR_STAND_ROLL || c->mode == QR_STAND_PITCH || c->mode == QR_STAND_YAW) {
        /* One degree of freedom about a body-fixed axis: w is parallel to the axis, so the
         * gyroscopic term w x Iw has no component along it. */
        double tau = c->axis[0] * torque_b[0] + c->axis[1] * torque_b[1] + c->axis[2] * torque_b[2];
        dy[QR_GIMBAL] = y[QR_GIMBAL + 1];
        dy[QR_GIMBAL + 1] = (tau - p->stand_damping * y[QR_GIMBAL + 1]) / c->axis_inertia;
        return;
    }
    if (c->mode < 0)
        return; /* resting on the ground: only the rotors move */

    const double *q = y + QR_QW;
    const double *w = y + QR_P;
    /* Quaternion kinematics: dq/dt = 0.5 q (x) (0, w). */
    dy[QR_QW + 0] = 0.5 * (-q[1] * w[0] - q[2] * w[1] - q[3] * w[2]);
    dy[QR_QW + 1] = 0.5 * (q[0] * w[0] + q[2] * w[2] - q[3] * w[1]);
    dy[QR_QW + 2] = 0.5 * (q[0] * w[1] - q[1] * w[2] + q[3] * w[0]);
    dy[QR_QW + 3] = 0.5 * (q[0] * w[2] + q[1] * w[1] - q[2] * w[0]);

    /* Euler's equations: I dw/dt = tau - w x (I w). */
    double I[3] = { p->Ixx, p->Iyy, p->Izz };
    double Iw[3] = { I[0] * w[0], I[1] * w[1], I[2] * w[2] };
    double gyro[3] = { w[1] * Iw[2] - w[2] * Iw[1], w[2] * Iw[0] - w[0] * Iw[2], w[0] * Iw[1] - w[1] * Iw[0] };
    double damp = c->mode == QR_STAND_ATTITUDE ? p->stand_damping : 0.0;
    for (int k = 0; k < 3; k++)
        dy[QR_P + k] = (torque_b[k] - gyro[k] - damp * w[k]) / I[k];

    if (c->mode == QR_STAND_ATTITUDE)
        return; /* position held by the gimbal */

    double R[3][3], acc[3];
    quat_to_dcm(q, R);
    free_accel(c, y, R, force_b, acc);
    for (int k = 0; k < 3; k++) {
        dy[QR_PN + k] = y[QR_VN + k];
        dy[QR_VN + k] = acc[k];
    }
}

/* Downward (positive) net force on a vehicle at rest on the ground with its current rotor speeds. */
static double resting_down_force(const ctx_t *c, const double *y)
{
    double force_b[3], torque_b[3], R[3][3], acc[3];
    double still[QR_NSTATE];
    memcpy(still, y, sizeof still);
    still[QR_VN] = still[QR_VN + 1] = still[QR_VN + 2] = 0;
    rotor_loads(c, still, force_b, torque_b);
    quat_to_dcm(still + QR_QW, R);
    free_accel(c, still, R, force_b, acc);
    return acc[2];
}

/* The arms' body coordinates for the frame and arm length. Kept from the last call: make_ctx runs
 * twice a step (the step, then its outputs), and its eight sines and cosines were about an eighth of
 * the plant's instructions (bench/cycle_cost.py --breakdown) for values that change only with two
 * parameters. The same calls on the same arguments when they do change: bit for bit what computing
 * them every time gives. Thread-local: a sweep may step plants in several threads of one process. */
static void arm_coordinates(const qr_params *p, double x[4], double y[4])
{
    static _Thread_local struct {
        int valid, frame;
        double length, x[4], y[4];
    } memo;
    if (!memo.valid || memo.frame != p->frame || memo.length != p->arm_length) { /* (NaN: never equal) */
        for (int i = 0; i < 4; i++) {
            double a = ARM_ANGLE[i] + (p->frame == 1 ? QR_PI / 4 : 0.0);
            memo.x[i] = p->arm_length * cos(a);
            memo.y[i] = p->arm_length * sin(a);
        }
        memo.valid = 1;
        memo.frame = p->frame;
        memo.length = p->arm_length;
    }
    memcpy(x, memo.x, sizeof memo.x);
    memcpy(y, memo.y, sizeof memo.y);
}

/* What rotor_loads and free_accel read: the parameters, the inputs, the arms and the rotors' health
 * (the outputs need no more; the ESC commands were about a third of make_ctx's instructions there) */
static void loads_ctx(const qr_params *p, const qr_inputs *in, ctx_t *c)
{
    c->par = p;
    c->in = in;
    arm_coordinates(p, c->arm_x, c->arm_y);
    for (int i = 0; i < 4; i++)
        c->health[i] = isfinite(in->motor_health[i]) && in->motor_health[i] > 0 ? in->motor_health[i] : 0.0;
}

static void make_ctx(const qr_params *p, const qr_inputs *in, ctx_t *c)
{
    loads_ctx(p, in, c);
    for (int i = 0; i < 4; i++)
        c->omega_cmd[i] = qr_esc_omega_cmd(p, i, in->pwm_us[i]);
    c->mode = p->stand;
    /* Axis of a single-axis stand in body axes (constant, since the other two angles are held):
     * roll turns about body x; pitch about the intermediate y axis, which is (0, cos r0, -sin r0) in
     * body axes; yaw about world down, which is the third row of the initial body->world DCM. */
    c->axis[0] = c->axis[1] = c->axis[2] = 0;
    if (p->stand == QR_STAND_ROLL) {
        c->axis[0] = 1;
    } else if (p->stand == QR_STAND_PITCH) {
        c->axis[1] = cos(p->roll0);
        c->axis[2] = -sin(p->roll0);
    } else if (p->stand == QR_STAND_YAW) {
        double q0[4], R[3][3];
        quat_from_euler(p->roll0, p->pitch0, p->yaw0, q0);
        quat_to_dcm(q0, R);
        for (int k = 0; k < 3; k++)
            c->axis[k] = R[2][k];
    }
    c->axis_inertia =
        c->axis[0] * c->axis[0] * p->Ixx + c->axis[1] * c->axis[1] * p->Iyy + c->axis[2] * c->axis[2] * p->Izz;
}

/* Single-axis stands: attitude = initial attitude turned by the gimbal angle about the axis. */
static void apply_gimbal(const qr_params *p, const ctx_t *c, double *y)
{
    double q0[4], dq[4], a = y[QR_GIMBAL];
    quat_from_euler(p->roll0, p->pitch0, p->yaw0, q0);
    dq[0] = cos(a / 2);
    for (int k = 0; k < 3; k++)
        dq[1 + k] = c->axis[k] * sin(a / 2);
    quat_mul(q0, dq, y + QR_QW);
    for (int k = 0; k < 3; k++)
        y[QR_P + k] = c->axis[k] * y[QR_GIMBAL + 1];
}

void qr_init_state(const qr_params *p, const qr_inputs *in, qr_state *s)
{
    ctx_t c;
    make_ctx(p, in, &c);
    memset(s, 0, sizeof *s);
    s->y[QR_PN] = p->pn0;
    s->y[QR_PN + 1] = p->pe0;
    s->y[QR_PN + 2] = p->pd0;
    quat_from_euler(p->roll0, p->pitch0, p->yaw0, s->y + QR_QW);
    for (int i = 0; i < 4; i++)
        s->y[QR_OMEGA + i] = c.omega_cmd[i];
    s->on_ground = p->stand == QR_STAND_FREE && p->pd0 >= 0;
}

static void rk4(const ctx_t *c, double *y, double h)
{
    double k1[QR_NSTATE], k2[QR_NSTATE], k3[QR_NSTATE], k4[QR_NSTATE], t[QR_NSTATE];
    derivatives(c, y, k1);
    for (int i = 0; i < QR_NSTATE; i++)
        t[i] = y[i] + 0.5 * h * k1[i];
    derivatives(c, t, k2);
    for (int i = 0; i < QR_NSTATE; i++)
        t[i] = y[i] + 0.5 * h * k2[i];
    derivatives(c, t, k3);
    for (int i = 0; i < QR_NSTATE; i++)
        t[i] = y[i] + h * k3[i];
    derivatives(c, t, k4);
    for (int i = 0; i < QR_NSTATE; i++)
        y[i] += h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
}

int qr_advance(const qr_params *p, const qr_inputs *in, qr_state *s, double dt)
{
    ctx_t c;
    make_ctx(p, in, &c);
    qr_state next = *s;
    long n = (long)ceil(dt / p->h_max_step - 1e-9);
    if (n < 1)
        n = 1;
    double h = dt / (double)n;
    for (long k = 0; k < n; k++) {
        if (p->stand == QR_STAND_FREE) {
            /* Leave the ground only when the net force points up. */
            if (next.on_ground && resting_down_force(&c, next.y) < 0)
                next.on_ground = 0;
            c.mode = next.on_ground ? -1 : QR_STAND_FREE;
        }
        rk4(&c, next.y, h);
        if (c.mode == QR_STAND_ROLL || c.mode == QR_STAND_PITCH || c.mode == QR_STAND_YAW)
            apply_gimbal(p, &c, next.y);
        else
            quat_normalize(next.y + QR_QW);
        if (c.mode == QR_STAND_FREE && next.y[QR_PN + 2] >= 0) {
            /* Touch-down: a perfectly inelastic, high-friction contact. The vehicle stops where it
             * is, keeps its attitude, and rests until thrust lifts it. */
            next.y[QR_PN + 2] = 0;
            for (int k = 0; k < 3; k++)
                next.y[QR_VN + k] = next.y[QR_P + k] = 0;
            next.on_ground = 1;
        }
    }
    for (int i = 0; i < QR_NSTATE; i++)
        if (!isfinite(next.y[i]))
            return -1;
    *s = next;
    return 0;
}

void qr_outputs_from(const qr_params *p, const qr_inputs *in, const qr_state *s, qr_outputs *o)
{
    ctx_t c;
    loads_ctx(p, in, &c);
    const double *y = s->y;
    const double *q = y + QR_QW;
    double R[3][3];
    quat_to_dcm(q, R);
    for (int k = 0; k < 3; k++) {
        o->pos[k] = y[QR_PN + k];
        o->vel[k] = y[QR_VN + k];
        o->rate[k] = y[QR_P + k];
    }
    for (int k = 0; k < 4; k++)
        o->q[k] = q[k];
    o->roll = atan2(2 * (q[0] * q[1] + q[2] * q[3]), 1 - 2 * (q[1] * q[1] + q[2] * q[2]));
    o->pitch = asin(clamp(2 * (q[0] * q[2] - q[3] * q[1]), -1.0, 1.0));
    o->yaw = atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] * q[2] + q[3] * q[3]));

    /* Specific force = R^T (a - g). Held vehicles (stands, resting) do not accelerate. */
    double acc[3] = { 0, 0, 0 };
    if (p->stand == QR_STAND_FREE && !s->on_ground) {
        double force_b[3], torque_b[3];
        rotor_loads(&c, y, force_b, torque_b);
        free_accel(&c, y, R, force_b, acc);
    }
    acc[2] -= p->gravity;
    mat_t_vec(R, acc, o->f_body);
    mat_t_vec(R, p->mag, o->mag_body);

    double h = -y[QR_PN + 2];
    o->pressure = qr_isa_pressure(p, h);
    o->temperature = qr_isa_temperature(p, h);
    for (int i = 0; i < 4; i++) {
        o->omega[i] = y[QR_OMEGA + i];
        o->thrust[i] = p->k_thrust * c.health[i] * y[QR_OMEGA + i] * y[QR_OMEGA + i];
    }
    o->on_ground = s->on_ground;
}
