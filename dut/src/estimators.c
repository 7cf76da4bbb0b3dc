/* Attitude estimators: seed 000's quaternion complementary filter, seed 002's Mahony filter on the DCM,
   and an EKF baseline (seed 002 compares against one). All three take the same body-frame gyro, accel
   and mag samples, so the rig can swap them by configuration and score each against truth. */
#include <math.h>
#include <string.h>

#include "fc.h"

vec3 v3(real x, real y, real z) { return (vec3){ x, y, z }; }
vec3 v3_add(vec3 a, vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
vec3 v3_scale(vec3 a, real k) { return v3(a.x * k, a.y * k, a.z * k); }
vec3 v3_cross(vec3 a, vec3 b) { return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x); }
real v3_dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
real v3_norm(vec3 a) { return sqrt(v3_dot(a, a)); }
vec3 v3_unit(vec3 a)
{
    real n = v3_norm(a);
    return n > 0 ? v3_scale(a, 1.0 / n) : a;
}

static void quat_normalise(real q[4])
{
    real n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int i = 0; i < 4; i++)
        q[i] /= n;
}

static void quat_to_dcm(const real q[4], real R[3][3])
{
    real w = q[0], x = q[1], y = q[2], z = q[3];
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

static vec3 mat_vec(const real R[3][3], vec3 v)
{
    return v3(R[0][0] * v.x + R[0][1] * v.y + R[0][2] * v.z, R[1][0] * v.x + R[1][1] * v.y + R[1][2] * v.z,
              R[2][0] * v.x + R[2][1] * v.y + R[2][2] * v.z);
}

static vec3 mat_t_vec(const real R[3][3], vec3 v)
{
    return v3(R[0][0] * v.x + R[1][0] * v.y + R[2][0] * v.z, R[0][1] * v.x + R[1][1] * v.y + R[2][1] * v.z,
              R[0][2] * v.x + R[1][2] * v.y + R[2][2] * v.z);
}

euler quat_to_euler(const real q[4])
{
    real w = q[0], x = q[1], y = q[2], z = q[3];
    real s = clampd(2 * (w * y - x * z), -1.0, 1.0);
    return (euler){ atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)), asin(s),
                    atan2(2 * (x * y + w * z), 1 - 2 * (y * y + z * z)) };
}

void euler_to_quat(euler e, real q[4])
{
    real cr = cos(e.roll / 2), sr = sin(e.roll / 2), cp = cos(e.pitch / 2), sp = sin(e.pitch / 2);
    real cy = cos(e.yaw / 2), sy = sin(e.yaw / 2);
    q[0] = cr * cp * cy + sr * sp * sy;
    q[1] = sr * cp * cy - cr * sp * sy;
    q[2] = cr * sp * cy + sr * cp * sy;
    q[3] = cr * cp * sy - sr * sp * cy;
}

/* Seed 000 eq. 3-4: Q(t+1) = [I (1 - dtheta^2/8) + dPhi/2] Q(t), dPhi = Omega(w) T. */
void picard2(real q[4], vec3 w, real T)
{
    real ax = w.x * T, ay = w.y * T, az = w.z * T;
    real c = 1.0 - (ax * ax + ay * ay + az * az) / 8.0;
    real q0 = q[0], q1 = q[1], q2 = q[2], q3 = q[3];
    q[0] = c * q0 + 0.5 * (-ax * q1 - ay * q2 - az * q3);
    q[1] = c * q1 + 0.5 * (ax * q0 + az * q2 - ay * q3);
    q[2] = c * q2 + 0.5 * (ay * q0 - az * q1 + ax * q3);
    q[3] = c * q3 + 0.5 * (az * q0 + ay * q1 - ax * q2);
    quat_normalise(q);
}

/* What a level, resting accelerometer reads, normalised, in body axes: minus gravity's direction. */
static vec3 predicted_up(const real R[3][3]) { return v3(-R[2][0], -R[2][1], -R[2][2]); }

/* The earth field as the estimate sees it, folded into the north-down plane (the reference vector of
   seed 000 eq. 1), then back in body axes. */
static vec3 predicted_field(const real R[3][3], vec3 m)
{
    vec3 h = mat_vec(R, m);
    vec3 b = v3(sqrt(h.x * h.x + h.y * h.y), 0.0, h.z);
    return mat_t_vec(R, b);
}

void quat_cf_init(quat_cf *f, real kp, real ki)
{
    memset(f, 0, sizeof *f);
    f->q[0] = 1.0;
    f->kp = kp;
    f->ki = ki;
}

void quat_cf_set_euler(quat_cf *f, euler e) { euler_to_quat(e, f->q); }

void quat_cf_update(quat_cf *f, vec3 gyro, vec3 accel, vec3 mag, real T)
{
    real R[3][3];
    quat_to_dcm(f->q, R);
    vec3 e = v3(0, 0, 0);
    if (v3_norm(accel) > 0)
        e = v3_add(e, v3_cross(v3_unit(accel), predicted_up(R))); /* eq. 1, accel part */
    if (v3_norm(mag) > 0) {
        vec3 m = v3_unit(mag);
        e = v3_add(e, v3_cross(m, predicted_field(R, m))); /* eq. 1, mag part */
    }
    f->integral = v3_add(f->integral, v3_scale(e, T));
    vec3 w = v3_add(gyro, v3_add(v3_scale(e, f->kp), v3_scale(f->integral, f->ki))); /* eq. 2 */
    picard2(f->q, w, T);
}

/* ---- Mahony on the DCM (seed 002 section 2.3) -------------------------------------------------------- */

void mahony_init(mahony_dcm *f, real kp, real ki)
{
    memset(f, 0, sizeof *f);
    f->R[0][0] = f->R[1][1] = f->R[2][2] = 1.0;
    f->kp = kp;
    f->ki = ki;
}

void mahony_set_euler(mahony_dcm *f, euler e)
{
    real q[4];
    euler_to_quat(e, q);
    quat_to_dcm(q, f->R);
}

euler dcm_to_euler(const real R[3][3])
{
    return (euler){ atan2(R[2][1], R[2][2]), asin(clampd(-R[2][0], -1.0, 1.0)), atan2(R[1][0], R[0][0]) };
}

/* Section 2.3.1: share the rows' dot product as error between r_x and r_y, rebuild r_z from them, and
   renormalise each row with the first-order Taylor step (3 - |r|^2) / 2. */
void dcm_orthonormalise(real R[3][3])
{
    vec3 rx = v3(R[0][0], R[0][1], R[0][2]), ry = v3(R[1][0], R[1][1], R[1][2]);
    real err = v3_dot(rx, ry);
    vec3 rx2 = v3_add(rx, v3_scale(ry, -err / 2)), ry2 = v3_add(ry, v3_scale(rx, -err / 2));
    vec3 rz2 = v3_cross(rx2, ry2);
    vec3 rows[3] = { rx2, ry2, rz2 };
    for (int i = 0; i < 3; i++) {
        vec3 r = v3_scale(rows[i], 0.5 * (3.0 - v3_dot(rows[i], rows[i])));
        R[i][0] = r.x;
        R[i][1] = r.y;
        R[i][2] = r.z;
    }
}

void mahony_update(mahony_dcm *f, vec3 gyro, vec3 accel, vec3 mag, real T)
{
    vec3 e = v3(0, 0, 0);
    if (v3_norm(accel) > 0)
        e = v3_add(e, v3_cross(v3_unit(accel), predicted_up(f->R))); /* zeta = a x d */
    if (v3_norm(mag) > 0) {
        /* yaw only: the measured field in earth axes, projected on the horizontal plane, against north */
        vec3 me = mat_vec(f->R, v3_unit(mag));
        vec3 mh = v3_unit(v3(me.x, me.y, 0.0));
        vec3 eps_earth = v3_cross(mh, v3(1, 0, 0));
        e = v3_add(e, mat_t_vec(f->R, eps_earth)); /* epsilon in body axes */
    }
    f->integral = v3_add(f->integral, v3_scale(e, T));
    vec3 w = v3_add(gyro, v3_add(v3_scale(e, f->kp), v3_scale(f->integral, f->ki)));
    real a = w.x * T, b = w.y * T, c = w.z * T; /* R = R (I + [w T]x) */
    real Om[3][3] = { { 1, -c, b }, { c, 1, -a }, { -b, a, 1 } }, N[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            N[i][j] = f->R[i][0] * Om[0][j] + f->R[i][1] * Om[1][j] + f->R[i][2] * Om[2][j];
    memcpy(f->R, N, sizeof N);
    dcm_orthonormalise(f->R);
}

/* ---- EKF ---------------------------------------------------------------------------------------------- */

void ekf_init(ekf7 *f)
{
    memset(f, 0, sizeof *f);
    f->x[0] = 1.0;
    for (int i = 0; i < 4; i++)
        f->P[i][i] = 0.1;
    for (int i = 4; i < 7; i++)
        f->P[i][i] = 1e-4;
    f->q_gyro = 1e-6; /* per second, on the quaternion */
    f->q_bias = 1e-10;
    f->r_acc = 1e-2;
    f->r_mag = 1e-2;
}

void ekf_set_euler(ekf7 *f, euler e) { euler_to_quat(e, f->x); }
euler ekf_euler(const ekf7 *f) { return quat_to_euler(f->x); }

static void ekf_measure(const real x[7], vec3 m_body, real z[6])
{
    real R[3][3];
    real q[4] = { x[0], x[1], x[2], x[3] };
    quat_normalise(q);
    quat_to_dcm(q, R);
    vec3 up = predicted_up(R), fld = v3_unit(predicted_field(R, m_body));
    z[0] = up.x;
    z[1] = up.y;
    z[2] = up.z;
    z[3] = fld.x;
    z[4] = fld.y;
    z[5] = fld.z;
}

/* Solves S X = B for X (n <= 6, m columns) by Gauss-Jordan with partial pivoting; 0 if singular. */
static int solve(int n, real S[6][6], int m, real B[6][7])
{
    for (int c = 0; c < n; c++) {
        int p = c;
        for (int r = c + 1; r < n; r++)
            if (fabs(S[r][c]) > fabs(S[p][c]))
                p = r;
        if (fabs(S[p][c]) < FC_TINY)
            return 0;
        for (int k = 0; k < n; k++) {
            real t = S[c][k];
            S[c][k] = S[p][k];
            S[p][k] = t;
        }
        for (int k = 0; k < m; k++) {
            real t = B[c][k];
            B[c][k] = B[p][k];
            B[p][k] = t;
        }
        for (int r = 0; r < n; r++) {
            if (r == c)
                continue;
            real k = S[r][c] / S[c][c];
            for (int j = 0; j < n; j++)
                S[r][j] -= k * S[c][j];
            for (int j = 0; j < m; j++)
                B[r][j] -= k * B[c][j];
        }
    }
    for (int r = 0; r < n; r++)
        for (int j = 0; j < m; j++)
            B[r][j] /= S[r][r];
    return 1;
}

void ekf_update(ekf7 *f, vec3 gyro, vec3 accel, vec3 mag, real T)
{
    real *x = f->x;
    /* predict: q' = (I + Omega(w - b) T / 2) q, b' = b */
    vec3 w = v3(gyro.x - x[4], gyro.y - x[5], gyro.z - x[6]);
    real F[7][7] = { { 0 } };
    real hx = w.x * T / 2, hy = w.y * T / 2, hz = w.z * T / 2;
    real Phi[4][4] = { { 1, -hx, -hy, -hz }, { hx, 1, hz, -hy }, { hy, -hz, 1, hx }, { hz, hy, -hx, 1 } };
    real q0 = x[0], q1 = x[1], q2 = x[2], q3 = x[3];
    real Xi[4][3] = { { -q1, -q2, -q3 }, { q0, -q3, q2 }, { q3, q0, -q1 }, { -q2, q1, q0 } };
    for (int i = 0; i < 4; i++) {
        for (int j = 0; j < 4; j++)
            F[i][j] = Phi[i][j];
        for (int j = 0; j < 3; j++)
            F[i][4 + j] = -Xi[i][j] * T / 2;
    }
    for (int i = 4; i < 7; i++)
        F[i][i] = 1;
    real xq[4];
    for (int i = 0; i < 4; i++)
        xq[i] = Phi[i][0] * q0 + Phi[i][1] * q1 + Phi[i][2] * q2 + Phi[i][3] * q3;
    memcpy(x, xq, sizeof xq);
    quat_normalise(x);
    real FP[7][7] = { { 0 } }, P2[7][7] = { { 0 } };
    for (int i = 0; i < 7; i++)
        for (int j = 0; j < 7; j++)
            for (int k = 0; k < 7; k++)
                FP[i][j] += F[i][k] * f->P[k][j];
    for (int i = 0; i < 7; i++)
        for (int j = 0; j < 7; j++) {
            for (int k = 0; k < 7; k++)
                P2[i][j] += FP[i][k] * F[j][k];
            if (i == j)
                P2[i][j] += (i < 4 ? f->q_gyro : f->q_bias) * T;
        }
    memcpy(f->P, P2, sizeof P2);
    if (v3_norm(accel) <= 0 || v3_norm(mag) <= 0)
        return;
    /* update with the accel and mag directions; H by central differences (the model is small) */
    vec3 a = v3_unit(accel), m = v3_unit(mag);
    real z[6] = { a.x, a.y, a.z, m.x, m.y, m.z }, h[6], H[6][7];
    ekf_measure(x, m, h);
    for (int j = 0; j < 7; j++) {
        real xp[7], xm[7], hp[6], hm[6];
        memcpy(xp, x, sizeof xp);
        memcpy(xm, x, sizeof xm);
        xp[j] += FC_EKF_DX;
        xm[j] -= FC_EKF_DX;
        ekf_measure(xp, m, hp);
        ekf_measure(xm, m, hm);
        for (int i = 0; i < 6; i++)
            H[i][j] = (hp[i] - hm[i]) / (2 * FC_EKF_DX);
    }
    real PHt[7][6] = { { 0 } }, S[6][6] = { { 0 } }, B[6][7];
    for (int i = 0; i < 7; i++)
        for (int j = 0; j < 6; j++)
            for (int k = 0; k < 7; k++)
                PHt[i][j] += f->P[i][k] * H[j][k];
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 6; j++) {
            for (int k = 0; k < 7; k++)
                S[i][j] += H[i][k] * PHt[k][j];
            if (i == j)
                S[i][j] += i < 3 ? f->r_acc : f->r_mag;
        }
    for (int i = 0; i < 6; i++) /* B = (P H^T)^T, so that solving S K^T = B gives the gain */
        for (int j = 0; j < 7; j++)
            B[i][j] = PHt[j][i];
    if (!solve(6, S, 7, B))
        return;
    for (int i = 0; i < 7; i++) /* x += K (z - h), K = B^T */
        for (int j = 0; j < 6; j++)
            x[i] += B[j][i] * (z[j] - h[j]);
    quat_normalise(x);
    real KH[7][7] = { { 0 } }, P3[7][7] = { { 0 } };
    for (int i = 0; i < 7; i++)
        for (int j = 0; j < 7; j++)
            for (int k = 0; k < 6; k++)
                KH[i][j] += B[k][i] * H[k][j];
    for (int i = 0; i < 7; i++)
        for (int j = 0; j < 7; j++)
            for (int k = 0; k < 7; k++)
                P3[i][j] += ((i == k) - KH[i][k]) * f->P[k][j];
    memcpy(f->P, P3, sizeof P3);
}
