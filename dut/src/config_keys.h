/* The reference FC's configuration keys, written once: config.c compiles this table into its parser,
   and the rig's scenario checker reads it (scenarios/fc_keys.py), so a key the FC does not know, a
   value of the wrong kind or out of range fails `rig validate` before anything flies.

   FC_KEY(name, kind, count, low, high): kind D is `count` numbers, I an integer, S a path or word;
   a number outside [low, high] is refused (ANY: no limit). Rules that relate two keys stay in
   config_load (ctrl_rate_hz <= est_rate_hz). "profile" (FC_PROFILES) sets several gains at once. */
#ifndef CONFIG_KEYS_H
#define CONFIG_KEYS_H

#define FC_PROFILES(PROFILE) PROFILE(default) PROFILE(seed002)

#define FC_CONFIG_KEYS(FC_KEY)               \
    FC_KEY(i2c_path, S, 1, 0, 0)             \
    FC_KEY(mpu_addr, I, 1, 0, 127)           \
    FC_KEY(hmc_addr, I, 1, 0, 127)           \
    FC_KEY(baro_addr, I, 1, 0, 127)          \
    FC_KEY(rc_path, S, 1, 0, 0)              \
    FC_KEY(telemetry_path, S, 1, 0, 0)       \
    FC_KEY(pwm_chip, I, 1, 0, 1000)          \
    FC_KEY(estimator, I, 1, 0, 2)            \
    FC_KEY(mixer, I, 1, 0, 1)                \
    FC_KEY(est_rate_hz, D, 1, 10, 2000)      \
    FC_KEY(ctrl_rate_hz, D, 1, 10, 2000)     \
    FC_KEY(defect_mixer_sign, I, 1, 0, 1)    \
    FC_KEY(defect_never_arm, I, 1, 0, 1)     \
    FC_KEY(gyro_fault_check, I, 1, 0, 1)     \
    FC_KEY(defect_crash_at, D, 1, 0, ANY)    \
    FC_KEY(kp_est, D, 1, 0, ANY)             \
    FC_KEY(ki_est, D, 1, 0, ANY)             \
    FC_KEY(angle_kp, D, 1, ANY, ANY)         \
    FC_KEY(angle_ki, D, 1, ANY, ANY)         \
    FC_KEY(angle_kd, D, 1, ANY, ANY)         \
    FC_KEY(rate_kp, D, 1, ANY, ANY)          \
    FC_KEY(rate_ki, D, 1, ANY, ANY)          \
    FC_KEY(rate_kd, D, 1, ANY, ANY)          \
    FC_KEY(yaw_rate_kp, D, 1, ANY, ANY)      \
    FC_KEY(yaw_rate_ki, D, 1, ANY, ANY)      \
    FC_KEY(alt_sp_range_m, D, 1, 0, 100)     \
    FC_KEY(alt_kp, D, 1, ANY, ANY)           \
    FC_KEY(alt_ki, D, 1, ANY, ANY)           \
    FC_KEY(alt_kd, D, 1, ANY, ANY)           \
    FC_KEY(alt_kv, D, 1, ANY, ANY)           \
    FC_KEY(alt_i_band_m, D, 1, 0, ANY)       \
    FC_KEY(baro_gate_m, D, 1, 0, ANY)        \
    FC_KEY(acc_kp, D, 1, ANY, ANY)           \
    FC_KEY(acc_ki, D, 1, ANY, ANY)           \
    FC_KEY(acc_kd, D, 1, ANY, ANY)           \
    FC_KEY(angle_limit, D, 1, 0, ANY)        \
    FC_KEY(alt_limit, D, 1, 0, ANY)          \
    FC_KEY(hover_us, D, 1, 1000, 2000)       \
    FC_KEY(max_angle_deg, D, 1, 0, 90)       \
    FC_KEY(max_yaw_rate_dps, D, 1, 0, ANY)   \
    FC_KEY(alpha, D, 4, ANY, ANY)            \
    FC_KEY(beta, D, 4, ANY, ANY)             \
    FC_KEY(acc_offset, D, 3, ANY, ANY)       \
    FC_KEY(acc_scale, D, 3, ANY, ANY)        \
    FC_KEY(mag_offset, D, 3, ANY, ANY)       \
    FC_KEY(mag_scale, D, 3, ANY, ANY)        \
    FC_KEY(telemetry_every, I, 1, 1, 100000) \
    FC_KEY(telemetry_proto, I, 1, 0, 2)      \
    FC_KEY(arming, I, 1, 0, 1)               \
    FC_KEY(arm_hold_s, D, 1, 0, 10)          \
    FC_KEY(sbus_map, I, 1, 0, 1)

#endif
