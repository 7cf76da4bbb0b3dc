/*
 * PWM duty notices in the fast path (part of fastpath.c, one translation unit: it includes this file).
 *
 * A duty write sets the motor's input as World.apply_pwm does, from the channel's settings: exported,
 * enabled, period and polarity. Those are the handler's to change (the other PWM notices are its own,
 * never the fast path's), so they are read from the Python channel objects once and kept here until
 * the handler says it changed one (Handler.pwm_config_changes, looked at once per handle() call, at
 * its first duty write). Reading them at every write, with World.direct_pwm, was about a tenth of an
 * FC cycle's instructions (bench/cycle_cost.py --breakdown). The duty goes into the channel's duty_ns
 * cell (PwmChannel.duty_addr, found with the settings; the channel is held while kept), where the
 * handler's writes go too: the Python side reads the mirror as before.
 */

/* a PwmChannel attribute as an int64 (0: it did not fit, the handler takes the message) */
static int channel_attr(PyObject *ch, PyObject *name, long long *out)
{
    PyObject *v = attr_get(ch, name);
    if (!v)
        return -1;
    int overflow = 0;
    *out = PyLong_AsLongLongAndOverflow(v, &overflow);
    Py_DECREF(v);
    if (*out == -1 && PyErr_Occurred())
        return -1;
    return overflow || *out < 0 ? 0 : 1;
}

/* The kept settings are current: the handler's change count and World.direct_pwm read once per
 * handle() call; a change since the last look forgets every channel's. 1, or -1 on an error. */
static int pwm_settings_current(fast_state *s)
{
    pwm_cache *c = &s->pwm_seen;
    if (c->checked)
        return 1;
    PyObject *v = attr_get(s->handler, s_pwm_config_changes);
    if (!v)
        return -1;
    long long changes = PyLong_AsLongLong(v);
    Py_DECREF(v);
    if (changes == -1 && PyErr_Occurred())
        return -1;
    PyObject *direct = attr_get(s->world, s_direct_pwm);
    if (!direct)
        return -1;
    int is_direct = PyObject_IsTrue(direct);
    Py_DECREF(direct);
    if (is_direct < 0)
        return -1;
    if (changes != c->changes) /* (the state starts zeroed: nothing known, as the handler's 0 says) */
        memset(c->known, 0, sizeof c->known);
    c->changes = changes, c->is_direct = is_direct, c->checked = 1;
    return 1;
}

/* channel ``i``'s settings, read from its object unless kept: 1, 0 (one did not fit: the handler's), -1 */
static int pwm_settings(fast_state *s, Py_ssize_t i, long long v[4])
{
    pwm_cache *c = &s->pwm_seen;
    if (!c->known[i]) {
        PyObject *ch = PyList_GET_ITEM(s->pwm, i);
        PyObject *names[4] = { s_exported, s_enabled, s_period_ns, s_inversed };
        for (int k = 0; k < 4; k++) {
            int r = channel_attr(ch, names[k], &c->settings[i][k]);
            if (r <= 0)
                return r;
        }
        c->duty[i] = address_attr(ch, "duty_addr");
        if (!c->duty[i])
            return PyErr_Occurred() ? -1 : 0;
        Py_INCREF(ch);
        Py_XSETREF(c->channel[i], ch);
        c->known[i] = 1;
    }
    memcpy(v, c->settings[i], sizeof c->settings[i]);
    return 1;
}

static int pwm(fast_state *s, const struct rig_hdr *h, const uint8_t *p)
{
    struct rig_pwm_msg m;
    if (h->len != sizeof m)
        return 0;
    memcpy(&m, p, sizeof m);
    if (m.chip != 0 || m.attr != RIG_PWM_DUTY || m.channel >= PyList_GET_SIZE(s->pwm) || m.channel >= RIG_PWM_MAX ||
        m.value > INT64_MAX)
        return 0;
    int clear = clear_until(s, h->t_ns, 0);
    if (clear <= 0)
        return clear;
    /* PwmChannel.pulse_us with the new duty, its settings known before anything moves */
    long long set[4]; /* exported, enabled, period, inversed */
    int r = pwm_settings_current(s);
    if (r > 0)
        r = pwm_settings(s, m.channel, set);
    if (r <= 0)
        return r;
    /* acting from here on: Scheduler.advance, then the handler's PWM notice */
    if (world_to(s, h->t_ns) < 0)
        return -1;
    *s->pwm_seen.duty[m.channel] = m.value;
    if (m.channel < s->motors && s->pwm_seen.is_direct) { /* World.apply_pwm */
        double pulse = 0.0;
        long long period = set[2];
        if (set[0] && set[1] && period > 0) {
            long long duty = (long long)m.value, high = set[3] ? period - duty : duty;
            high = high < 0 ? 0 : high;
            pulse = (double)(high < period ? high : period) / 1000.0;
        }
        s->u[s->u_pwm[m.channel]] = pulse;
    }
    return 1;
}
