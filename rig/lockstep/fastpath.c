/* The lockstep session's per-cycle messages in C, ``_riglockstep``: I2C transfers, PWM duty writes and
 * waits of a DUT in lockstep, answered without the Python handler (rig/handler.py), which stays the
 * reference and keeps everything else.
 *
 * Why: a flight controller's cycle is one I2C burst read, four PWM duty notices and one wait. Parsed
 * and dispatched as Python objects these cost about twice the plant and the samples together.
 *
 * How: handle() takes the connection's buffered bytes and acts on whole messages, in order, for as long
 * as each is one it takes: an I2C transfer, a PWM duty write, a WAIT, with no scheduled event due at
 * or before its time, the run's limit not reached, and nothing malformed. At the first message it does
 * not take it returns that message's offset, untouched, and the Python handler acts on it (HELLO,
 * NOTE, other PWM attributes, anything malformed, an event due, the end of the run). A message is
 * checked completely before anything happens, so declining it leaves no trace.
 *
 * What it does is what the handler does, in the same order: the world is run to the message's time
 * (World.advance_to), the chip core (emulators/chips/) transfers, the needs it reports are made by the
 * same Python producers (ChipBoard.serve), PWM duty sets the motor's input as World.apply_pwm does, the
 * plant steps as World.advance_to steps it (rig_plant_steps, the plant's own C), and the clock page,
 * the reply, the counts and the transfer log (run.mcap's /i2c) come out the same. The chip core's
 * entry points are the emulators' library's own (addresses from emulators/native.py), so one chip core
 * runs a session, whichever path serves a message.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <sys/socket.h>

#include "chip_core.h"
#include "need_tuple.h"
#include "plant_steps.c" /* rig_plant_steps: the plant's steps, the plant's own code */
#include "protocol.h"
#include "queue.h" /* the scheduler's events (rig/event_queue) */

#define MAX_MSGS 42      /* rig/protocol.py I2C_RDWR_MAX_MSGS */
#define I2C_MAX_LEN 8192 /* rig/protocol.py I2C_MAX_LEN */
#define I2C_M_RD 0x0001
#define I2C_M_TEN 0x0010
#define I2C_M_RECV_LEN 0x0400
#define NS 1000000000ull
#define FOREVER_SLICE_NS 10000000ull /* rig/handler.py FOREVER_SLICE_NS */
#define I2C_LOG_CAP 1000000          /* rig/handler.py I2C_LOG_CAP */
#define REPLY_MAX (sizeof(struct rig_hdr) + MAX_MSGS * (I2C_MAX_LEN + 1))

typedef int (*transfer_fn)(chip_board *, uint64_t, chip_msg *, uint32_t, chip_need *, uint32_t *);
typedef chip_need (*advance_fn)(chip_board *, uint64_t);

#include "attrs.c" /* the attributes read and written each cycle */
#include "imu_feed.c"

/* the PWM channels' settings, kept between duty writes (pwm_duty.c) */
typedef struct {
    long long changes;                  /* Handler.pwm_config_changes when they were read (0 at first) */
    int checked;                        /* changes read in this handle() call */
    int is_direct;                      /* World.direct_pwm */
    uint8_t known[RIG_PWM_MAX];         /* settings[i] read since the last change */
    long long settings[RIG_PWM_MAX][4]; /* exported, enabled, period_ns, inversed */
    PyObject *channel[RIG_PWM_MAX];     /* the PwmChannel they were read from (held: its duty cell) */
    uint64_t *duty[RIG_PWM_MAX];        /* its duty_ns cell (PwmChannel.duty_addr) */
} pwm_cache;

struct mbox_table; /* (mailbox.c) */
static void mbox_release(struct mbox_table *t);
typedef struct mag_feed mag_feed;   /* (mag_feed.c) */
typedef struct baro_feed baro_feed; /* (baro_feed.c) */
static void mag_release(mag_feed *f);
static void baro_release(baro_feed *f);

typedef struct {
    imu_feed imu;                   /* the IMU's samples in C (imu_feed.c), when setup_imu said so */
    mag_feed *mag;                  /* the magnetometer's (mag_feed.c), when setup_mag said so */
    baro_feed *baro;                /* the barometer's (baro_feed.c), when setup_baro said so */
    PyObject *world_advance;        /* World.advance_to */
    PyObject *serve;                /* ChipBoard.serve */
    PyObject *pwm;                  /* World.pwm: the PwmChannel list */
    event_queue *events;            /* Scheduler.events (rig/event_queue: its first event read here) */
    PyObject *sched;                /* Scheduler */
    PyObject *over;                 /* Scheduler.over_byte: its ``over`` as a bytearray's byte */
    PyObject *i2c_log;              /* Handler.i2c_log */
    PyTypeObject *record;           /* its rows' type (scenarios.result.I2CRecord, a tuple's subclass) */
    PyObject *handler;              /* Handler (its counts) */
    PyObject *page_obj;             /* the clock page's mmap, its buffer held */
    PyObject *world, *plant, *hist; /* for the plant's steps in C (World.advance_to's) */
    struct rig_plant_steps *steps;  /* the plant's, once it has stepped into the world's history */
    double *u;                      /* the plant's inputs (Plant.u) */
    int64_t *k;                     /* World._k's cell (World.k_addr) */
    int64_t u_pwm[RIG_PWM_MAX];     /* World._u_pwm: the input of motor channel i */
    Py_ssize_t motors;
    PyObject *step_calls;           /* plant.fmu._STEP_CALLS: a failed call's name */
    PyObject *run_next, *in_flight; /* the events a wait crosses (events.c) */
    Py_buffer page;
    chip_board *board;
    transfer_fn transfer;
    advance_fn advance;
    uint64_t step_ns, stepped_to, limit_ns, i2c_clock_hz;
    uint64_t handled;   /* messages acted on here (the rest went to the Python handler) */
    uint64_t counts[4]; /* of those: I2C transfers, waits, PWM writes, promised writes (+ the handler's) */
    pwm_cache pwm_seen; /* the channels' settings as last read (pwm_duty.c) */
    unsigned bus;
    uint8_t *rx;               /* pump()'s receive buffer, once it has run (pump.c) */
    struct mbox_table *mboxes; /* the connections' mailboxes, once one is open (mailbox.c) */
    uint8_t reply[REPLY_MAX];
} fast_state;

static uint64_t handled_total; /* messages acted on here by every session of this process */

static PyObject *s_steps_at, *s_ring, *s_direct_pwm, *s_exported, *s_enabled, *s_period_ns, *s_inversed;
static PyObject *s_over_byte, *s_pwm_config_changes;

static volatile uint64_t *sim_ns(fast_state *s)
{
    return (volatile uint64_t *)((char *)s->page.buf + offsetof(struct rig_shm, sim_ns));
}

static void page_set(fast_state *s, uint64_t t)
{
    if (t > *sim_ns(s))
        *sim_ns(s) = t;
}

static void state_free(PyObject *capsule)
{
    fast_state *s = PyCapsule_GetPointer(capsule, "rig.lockstep");
    if (!s)
        return;
    imu_free(&s->imu);
    for (int i = 0; i < RIG_PWM_MAX; i++)
        Py_XDECREF(s->pwm_seen.channel[i]);
    mag_release(s->mag);
    baro_release(s->baro);
    PyMem_Free(s->rx);
    mbox_release(s->mboxes);
    Py_XDECREF(s->world_advance);
    Py_XDECREF(s->serve);
    Py_XDECREF(s->pwm);
    Py_XDECREF(s->events);
    Py_XDECREF(s->sched);
    Py_XDECREF(s->over);
    Py_XDECREF(s->i2c_log);
    Py_XDECREF(s->record);
    Py_XDECREF(s->handler);
    Py_XDECREF(s->world);
    Py_XDECREF(s->plant);
    Py_XDECREF(s->hist);
    Py_XDECREF(s->step_calls);
    Py_XDECREF(s->run_next);
    Py_XDECREF(s->in_flight);
    if (s->page_obj) {
        PyBuffer_Release(&s->page);
        Py_DECREF(s->page_obj);
    }
    PyMem_Free(s);
}

/* setup(world_advance, serve, pwm, events, sched, i2c_log, handler, page_mmap, board_addr,
 *       transfer_addr, advance_addr, step_ns, limit_ns, i2c_clock_hz, bus, record_type) -> state */
static PyObject *fp_setup(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 16)
        return PyErr_Format(PyExc_TypeError, "setup takes 16 arguments (%zd given)", nargs);
    if (!PyList_Check(a[2]) || !PyList_Check(a[5]))
        return PyErr_Format(PyExc_TypeError, "setup: pwm and i2c_log are lists");
    if (!event_queue_check(a[3]))
        return PyErr_Format(PyExc_TypeError, "setup: the events are an EventQueue (rig/event_queue)");
    fast_state *s = PyMem_Calloc(1, sizeof *s);
    if (!s)
        return PyErr_NoMemory();
    PyObject *capsule = PyCapsule_New(s, "rig.lockstep", state_free);
    if (!capsule) {
        PyMem_Free(s);
        return NULL;
    }
    PyObject **refs[] = { &s->world_advance, &s->serve,   &s->pwm,    (PyObject **)&s->events,
                          &s->sched,         &s->i2c_log, &s->handler };
    for (int i = 0; i < 7; i++) {
        Py_INCREF(a[i]);
        *refs[i] = a[i];
    }
    if (PyObject_GetBuffer(a[7], &s->page, PyBUF_WRITABLE) < 0) {
        Py_DECREF(capsule);
        return NULL;
    }
    Py_INCREF(a[7]);
    s->page_obj = a[7];
    s->over = attr_get(s->sched, s_over_byte);
    if (!s->over || !PyByteArray_Check(s->over)) {
        Py_DECREF(capsule);
        return s->over ? PyErr_Format(PyExc_TypeError, "setup: the scheduler's over_byte is a bytearray") : NULL;
    }
    s->board = PyLong_AsVoidPtr(a[8]);
    s->transfer = (transfer_fn)PyLong_AsVoidPtr(a[9]);
    s->advance = (advance_fn)PyLong_AsVoidPtr(a[10]);
    s->step_ns = PyLong_AsUnsignedLongLong(a[11]);
    s->limit_ns = PyLong_AsUnsignedLongLong(a[12]);
    s->i2c_clock_hz = PyLong_AsUnsignedLongLong(a[13]);
    s->bus = (unsigned)PyLong_AsUnsignedLong(a[14]);
    if (!PyType_Check(a[15]) || !PyType_IsSubtype((PyTypeObject *)a[15], &PyTuple_Type) ||
        ((PyTypeObject *)a[15])->tp_basicsize != PyTuple_Type.tp_basicsize ||
        ((PyTypeObject *)a[15])->tp_itemsize != PyTuple_Type.tp_itemsize) {
        Py_DECREF(capsule);
        return PyErr_Format(PyExc_TypeError, "setup: the log's record type is a tuple's subclass with no fields of "
                                             "its own (a NamedTuple)");
    }
    Py_INCREF(a[15]);
    s->record = (PyTypeObject *)a[15];
    if (PyErr_Occurred()) {
        Py_DECREF(capsule);
        return NULL;
    }
    if (s->page.len < (Py_ssize_t)sizeof(struct rig_shm) || !s->board || !s->transfer || !s->advance || !s->step_ns) {
        Py_DECREF(capsule);
        return PyErr_Format(PyExc_ValueError, "setup: a page of %zu bytes and non-zero addresses and step",
                            sizeof(struct rig_shm));
    }
    return capsule;
}

/* setup_imu(state, feed, sampler, accel, gyro, accel_faults, gyro_faults, world, cols_addr, die_offset,
 *           block_addr, k0, history, hist_addr, row_bytes, max_depth, step_ns, reg_config, reg_smplrt_div,
 *           dlpf (8 rows of 4 numbers), measure_addr, lowpass_addr, push_addr, peek_addr): the IMU's
 * samples in C from now on (imu_feed.c); accel and gyro are the model's two channels (_Channel) */
static PyObject *fp_setup_imu(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 24)
        return PyErr_Format(PyExc_TypeError, "setup_imu takes 24 arguments (%zd given)", nargs);
    fast_state *s = PyCapsule_GetPointer(a[0], "rig.lockstep");
    return s ? imu_setup(&s->imu, a) : NULL;
}

/* setup_world(state, world, plant, hist, u_addr, u_pwm, motors, step_calls): the plant's steps and the
 * motors' inputs written here (World.advance_to's and World.apply_pwm's work) */
static PyObject *fp_setup_world(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 8)
        return PyErr_Format(PyExc_TypeError, "setup_world takes 8 arguments (%zd given)", nargs);
    fast_state *s = PyCapsule_GetPointer(a[0], "rig.lockstep");
    if (!s)
        return NULL;
    if (!PyList_Check(a[5]) || PyList_GET_SIZE(a[5]) > RIG_PWM_MAX || !PyDict_Check(a[7]))
        return PyErr_Format(PyExc_TypeError, "setup_world: u_pwm is a list of at most %d, step_calls a dict",
                            RIG_PWM_MAX);
    double *u = PyLong_AsVoidPtr(a[4]);
    int64_t *k = world_steps(a[1]);
    Py_ssize_t motors = PyLong_AsSsize_t(a[6]);
    int64_t idx[RIG_PWM_MAX];
    for (Py_ssize_t i = 0; i < PyList_GET_SIZE(a[5]) && !PyErr_Occurred(); i++)
        idx[i] = PyLong_AsLongLong(PyList_GET_ITEM(a[5], i));
    if (PyErr_Occurred())
        return NULL;
    if (!u || !k || motors < 0 || motors > PyList_GET_SIZE(a[5]))
        return PyErr_Format(PyExc_ValueError, "setup_world: input and step-count addresses and at most %zd motors",
                            PyList_GET_SIZE(a[5]));
    PyObject **refs[] = { &s->world, &s->plant, &s->hist, &s->step_calls };
    PyObject *objs[] = { a[1], a[2], a[3], a[7] };
    for (int i = 0; i < 4; i++) {
        Py_INCREF(objs[i]);
        Py_XSETREF(*refs[i], objs[i]);
    }
    s->u = u;
    s->k = k;
    s->motors = motors;
    memcpy(s->u_pwm, idx, sizeof(int64_t) * (size_t)motors);
    Py_RETURN_NONE;
}

/* ---- what the Python side keeps: events, the run's end ---- */

static int first_event_ns(fast_state *s, uint64_t *t); /* (events.c) */

/* 1: nothing the scheduler does stands between now and t (no event at or before t, the limit not
 * passed, the run not over; with runs_events, events due are the caller's to run: events.c);
 * 0: the Python handler must act */
static int clear_until(fast_state *s, uint64_t t, int runs_events)
{
    if (t > s->limit_ns)
        return 0;
    if (PyByteArray_GET_SIZE(s->over) < 1 || PyByteArray_AS_STRING(s->over)[0])
        return 0;
    if (runs_events && s->run_next)
        return 1;
    uint64_t first;
    return !first_event_ns(s, &first) || first > t;
}

/* the plant's step struct, once Plant.step_many has made it with the world's history as its ring */
static struct rig_plant_steps *plant_steps_of(fast_state *s)
{
    if (s->steps)
        return s->steps;
    PyObject *ring = attr_get(s->plant, s_ring);
    if (!ring)
        return NULL;
    int ours = ring == s->hist;
    Py_DECREF(ring);
    PyObject *at = ours ? attr_get(s->plant, s_steps_at) : NULL;
    if (at) {
        s->steps = PyLong_AsVoidPtr(at);
        Py_DECREF(at);
    }
    PyErr_Clear(); /* (no struct yet: World.advance_to makes it) */
    return s->steps;
}

/* Scheduler.advance with no event due: World.advance_to(t), its steps made here once the plant has its
 * struct (rig_plant_steps, as Plant.step_many calls it), World._k moved after them; a failed step raises
 * the plant's own error (Plant._fail). Called only when a whole step may have passed since the last. */
static int world_to(fast_state *s, uint64_t t)
{
    if (t / s->step_ns <= s->stepped_to / s->step_ns && s->stepped_to)
        return 0;
    struct rig_plant_steps *steps = plant_steps_of(s);
    if (steps) {
        int64_t k = *s->k;
        long long n = (long long)(t / s->step_ns) - k;
        if (n > 0) {
            int32_t done = rig_plant_steps(steps, (int32_t)n, (double)s->step_ns * 1e-9, 1, k + 1);
            if (done < n || steps->failed_call) {
                PyObject *code = PyLong_FromLong(steps->failed_call);
                PyObject *what = code ? PyDict_GetItemWithError(s->step_calls, code) : NULL; /* borrowed */
                Py_XDECREF(code);
                if (!PyErr_Occurred()) {
                    PyObject *r = what ? PyObject_CallMethod(s->plant, "_fail", "Oi", what, (int)steps->failed_status)
                                       : PyObject_CallMethod(s->plant, "_fail", "si", "rig_plant_steps",
                                                             (int)steps->failed_status);
                    Py_XDECREF(r);
                }
                if (!PyErr_Occurred())
                    PyErr_SetString(PyExc_RuntimeError, "the plant's step failed");
                return -1;
            }
            *s->k = k + n;
        }
    } else {
        PyObject *arg = PyLong_FromUnsignedLongLong(t);
        if (!arg)
            return -1;
        PyObject *r = PyObject_CallOneArg(s->world_advance, arg);
        Py_DECREF(arg);
        if (!r)
            return -1;
        Py_DECREF(r);
    }
    s->stepped_to = t;
    return 0;
}

#include "mag_feed.c"

#include "baro_feed.c" /* (after mag_feed.c: made_here reads both) */

static int serve(fast_state *s, const chip_need *need)
{
    int done = need->chip == CHIP_MPU    ? imu_serve(&s->imu, s->board, need)
               : need->chip == CHIP_HMC  ? mag_serve(s->mag, s->board, need)
               : need->chip == CHIP_BARO ? baro_serve(s->baro, s->board, need)
                                         : 0;
    if (done)
        return done < 0 ? -1 : 0;
    PyObject *t = need_tuple(need);
    if (!t)
        return -1;
    PyObject *r = PyObject_CallOneArg(s->serve, t);
    Py_DECREF(t);
    if (!r)
        return -1;
    Py_DECREF(r);
    return 0;
}

#include "mailbox.c" /* a connection's messages through shared memory in place of its socket */

#include "reply.c" /* send_all: a reply through the mailbox or the socket */

static void put_hdr(uint8_t *out, uint32_t len, uint16_t type, uint16_t status, uint64_t t)
{
    struct rig_hdr h = { len, type, status, t };
    memcpy(out, &h, sizeof h);
}

/* ---- the messages: 1 acted on, 0 for the Python handler (nothing done), -1 a Python error ---- */

#include "i2c_log.c"

/* A promised write (RIG_MSG_I2C_WRITE) that was not acknowledged: the DUT was told it was, so the run is
 * void (Handler.promise_broken) */
static int promise_broken(fast_state *s)
{
    PyObject *r = PyObject_CallMethod(s->handler, "promise_broken", NULL);
    Py_XDECREF(r);
    return r ? 1 : -1;
}

/* RIG_MSG_I2C (a request: the reply is sent) and RIG_MSG_I2C_WRITE (notice: one write message, at its own
 * time as the shim stamped it, no reply; Handler._i2c) */
static int i2c(fast_state *s, int fd, const struct rig_hdr *h, const uint8_t *p, int notice)
{
    uint16_t head[2];
    if (h->len < sizeof head)
        return 0;
    memcpy(head, p, sizeof head);
    uint32_t n = head[1];
    if (n < 1 || n > MAX_MSGS)
        return 0;
    size_t at = sizeof head + n * sizeof(struct rig_i2c_msg);
    if (h->len < at)
        return 0;
    struct rig_i2c_msg m[MAX_MSGS];
    memcpy(m, p + sizeof head, n * sizeof m[0]);
    const uint8_t *data[MAX_MSGS];
    for (uint32_t i = 0; i < n; i++) {
        if (m[i].len > I2C_MAX_LEN)
            return 0;
        data[i] = p + at;
        if (!(m[i].flags & I2C_M_RD)) {
            if (h->len - at < m[i].len)
                return 0;
            at += m[i].len;
        }
    }
    if (at != h->len)
        return 0;
    const struct rig_ack *acks = (const struct rig_ack *)((char *)s->page.buf + offsetof(struct rig_shm, acks));
    if (notice && !rig_ack_promised(acks, head[0], n, m[0].addr, m[0].flags, m[0].len, h->t_ns))
        return 0; /* (not what the session promised: the handler says why) */
    uint64_t now = *sim_ns(s), t = notice || h->t_ns > now ? h->t_ns : now;
    int clear = clear_until(s, t, 0);
    if (clear <= 0)
        return clear;
    /* acting from here on */
    if (world_to(s, t) < 0)
        return -1;
    uint8_t *out = s->reply + sizeof(struct rig_hdr);
    chip_msg cm[MAX_MSGS];
    uint16_t status = 0;
    size_t got = 0;
    if (head[0] != s->bus) {
        status = ENODEV;
    } else {
        size_t off = 0;
        for (uint32_t i = 0; i < n; i++) {
            cm[i].addr = m[i].addr <= 0x7F && !(m[i].flags & I2C_M_TEN) ? (uint8_t)m[i].addr : 0;
            if (m[i].flags & I2C_M_RD) {
                int recv_len = (m[i].flags & I2C_M_RECV_LEN) != 0;
                cm[i].flags = (uint8_t)(CHIP_MSG_READ | (recv_len ? CHIP_MSG_RECV_LEN : 0));
                cm[i].len = (uint16_t)(recv_len ? 1 + CHIP_SMBUS_BLOCK_MAX : m[i].len);
                cm[i].buf = out + off;
                off += cm[i].len;
            } else {
                cm[i].flags = 0;
                cm[i].len = m[i].len;
                cm[i].buf = (uint8_t *)data[i];
            }
        }
        chip_need need;
        while ((need = s->advance(s->board, t)).chip != CHIP_NONE) /* ChipBus.advance_ns */
            if (serve(s, &need) < 0)
                return -1;
        uint32_t failed = 0;
        int st;
        while ((st = s->transfer(s->board, t, cm, n, &need, &failed)) == CHIP_NEED)
            if (serve(s, &need) < 0)
                return -1;
        if (st == CHIP_NACK) {
            status = ENXIO;
        } else if (st == CHIP_PROTOCOL) {
            status = EPROTO;
        } else { /* the reads' bytes, packed (a RECV_LEN read has its own length now) */
            for (uint32_t i = 0; i < n; i++) {
                if (!(cm[i].flags & CHIP_MSG_READ))
                    continue;
                memmove(out + got, cm[i].buf, cm[i].len);
                got += cm[i].len;
            }
        }
    }
    uint64_t t_after = t;
    if (s->i2c_clock_hz) { /* Handler._bus_time_ns: a failed transfer's reads count no bytes */
        uint64_t bits = 1;
        for (uint32_t i = 0; i < n; i++) {
            uint64_t k = m[i].flags & I2C_M_RD ? (status ? 0 : cm[i].len) : m[i].len;
            bits += 10 + 9 * k;
        }
        t_after += bits * NS / s->i2c_clock_hz;
    }
    page_set(s, t_after);
    if (log_transfer(s, t, m, n, data, out, got, status) < 0)
        return -1;
    if (notice && status)
        return promise_broken(s);
    if (notice) {
        s->counts[3]++;
        return 1;
    }
    put_hdr(s->reply, (uint32_t)got, RIG_MSG_I2C, status, t_after);
    return send_all(s, fd, s->reply, sizeof(struct rig_hdr) + got) < 0 ? -1 : 1;
}

#include "events.c"
#include "pwm_duty.c"

static int wait(fast_state *s, int fd, const struct rig_hdr *h, const uint8_t *p)
{
    struct {
        uint64_t wake;
        uint32_t kind, zero;
    } m;
    if (h->len != sizeof m)
        return 0;
    memcpy(&m, p, sizeof m);
    uint64_t woke;
    if (m.kind == RIG_WAIT_AHEAD) { /* Handler._wait's notice: the world caught up, no reply */
        if (m.wake == RIG_WAIT_FOREVER)
            return 0;
        uint64_t target = m.wake > h->t_ns ? m.wake : h->t_ns;
        int clear = clear_until(s, target, 1);
        if (clear <= 0)
            return clear;
        s->counts[1]++;
        if (run_due(s, target, 0, &woke) < 0 || world_to(s, target) < 0)
            return -1;
        return deliver_written(s) < 0 ? -1 : 1;
    }
    if (m.kind != RIG_WAIT_SLEEP && m.kind != RIG_WAIT_POLL)
        return 0;
    uint64_t now = *sim_ns(s), t = h->t_ns > now ? h->t_ns : now;
    uint32_t reason = RIG_WAKE_DEADLINE;
    uint64_t target = m.wake > t ? m.wake : t;
    if (m.wake == RIG_WAIT_FOREVER) {
        if (t > UINT64_MAX - FOREVER_SLICE_NS)
            return 0;
        target = t + FOREVER_SLICE_NS, reason = RIG_WAKE_SLICE;
    }
    int clear = clear_until(s, target, 1);
    if (clear <= 0)
        return clear;
    /* acting from here on: Handler._wait */
    s->counts[1]++;
    if (run_due(s, target, m.kind == RIG_WAIT_POLL, &woke) < 0)
        return -1;
    if (woke < target)
        target = woke, reason = RIG_WAKE_EVENT; /* (the world is at the event's time) */
    else if (world_to(s, target) < 0)
        return -1;
    page_set(s, target);
    if (deliver_written(s) < 0)
        return -1;
    put_hdr(s->reply, sizeof reason, RIG_MSG_WAIT, 0, target);
    memcpy(s->reply + sizeof(struct rig_hdr), &reason, sizeof reason);
    return send_all(s, fd, s->reply, sizeof(struct rig_hdr) + sizeof reason) < 0 ? -1 : 1;
}

/* Acts on the whole messages in buf[off:end] for as long as each is one the fast path takes; *r: 1 when
 * it stopped at the end of the whole messages, 0 at one for the Python handler, -1 at an error (raised).
 * Returns the offset of the first message not acted on. */
static Py_ssize_t handle_bytes(fast_state *s, int fd, const uint8_t *buf, Py_ssize_t off, Py_ssize_t end, int *r)
{
    uint64_t *counts = s->counts; /* transactions, waits, pwm_writes */
    s->pwm_seen.checked = 0;      /* (the handler may have acted on PWM settings since the last call) */
    *r = 1;
    while (end - off >= (Py_ssize_t)sizeof(struct rig_hdr)) {
        struct rig_hdr h;
        memcpy(&h, buf + off, sizeof h);
        if (h.len > RIG_MAX_PAYLOAD || (Py_ssize_t)(end - off - sizeof h) < (Py_ssize_t)h.len)
            break;
        const uint8_t *p = buf + off + sizeof h;
        int k;
        if (h.type == RIG_MSG_I2C || h.type == RIG_MSG_I2C_WRITE)
            k = i2c(s, fd, &h, p, h.type == RIG_MSG_I2C_WRITE), counts[0] += k > 0;
        else if (h.type == RIG_MSG_PWM)
            k = pwm(s, &h, p), counts[2] += k > 0;
        else if (h.type == RIG_MSG_WAIT)
            k = wait(s, fd, &h, p); /* (it counts the waits it takes: an event may end one with Stop) */
        else
            k = 0;
        if (k <= 0) {
            *r = k;
            break;
        }
        s->handled++;
        handled_total++;
        off += (Py_ssize_t)(sizeof h + h.len);
    }
    return off;
}

/* handle(state, fd, buf, off) -> the offset of the first message not acted on (the end of the whole
 * messages, or one for the Python handler). buf: the connection's bytearray, unchanged. */
static PyObject *fp_handle(PyObject *self, PyObject *const *a, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 4)
        return PyErr_Format(PyExc_TypeError, "handle takes 4 arguments (%zd given)", nargs);
    fast_state *s = PyCapsule_GetPointer(a[0], "rig.lockstep");
    int fd = (int)PyLong_AsLong(a[1]);
    Py_ssize_t off = PyLong_AsSsize_t(a[3]);
    if (!s || PyErr_Occurred())
        return NULL;
    if (!PyByteArray_Check(a[2]))
        return PyErr_Format(PyExc_TypeError, "handle takes the connection's bytearray");
    Py_ssize_t end = PyByteArray_GET_SIZE(a[2]);
    if (off < 0 || off > end)
        return PyErr_Format(PyExc_ValueError, "handle: offset %zd outside the buffer", off);
    int r;
    off = handle_bytes(s, fd, (const uint8_t *)PyByteArray_AS_STRING(a[2]), off, end, &r);
    return r < 0 ? NULL : PyLong_FromSsize_t(off);
}

#include "pump.c" /* pump(): the connection read and acted on in C while nothing else needs the session */

/* handled(state) -> the messages acted on here so far; handled(None): by every session of the process */
static PyObject *fp_handled(PyObject *self, PyObject *state)
{
    (void)self;
    if (state == Py_None)
        return PyLong_FromUnsignedLongLong(handled_total);
    fast_state *s = PyCapsule_GetPointer(state, "rig.lockstep");
    return s ? PyLong_FromUnsignedLongLong(s->handled) : NULL;
}

/* counts(state) -> (transactions, waits, pwm_writes, promised_writes) acted on here: the run's outcome adds them to the
 * handler's (kept here, not added to the handler's attributes at each call: that was 2 k instructions
 * of an FC cycle) */
static PyObject *fp_counts(PyObject *self, PyObject *state)
{
    (void)self;
    fast_state *s = PyCapsule_GetPointer(state, "rig.lockstep");
    return s ? Py_BuildValue("(KKKK)", (unsigned long long)s->counts[0], (unsigned long long)s->counts[1],
                             (unsigned long long)s->counts[2], (unsigned long long)s->counts[3])
             : NULL;
}

static PyMethodDef methods[] = {
    { "setup", (PyCFunction)(void (*)(void))fp_setup, METH_FASTCALL, "the fast path's state for a session" },
    { "setup_world", (PyCFunction)(void (*)(void))fp_setup_world, METH_FASTCALL, "the plant's steps in C" },
    { "setup_imu", (PyCFunction)(void (*)(void))fp_setup_imu, METH_FASTCALL, "the IMU's samples in C" },
    { "setup_mag", (PyCFunction)(void (*)(void))fp_setup_mag, METH_FASTCALL, "the magnetometer's in C" },
    { "setup_baro", (PyCFunction)(void (*)(void))fp_setup_baro, METH_FASTCALL, "the barometer's in C" },
    { "made_here", fp_made_here, METH_O, "the magnetometer's and barometer's samples made here" },
    { "setup_events", (PyCFunction)(void (*)(void))fp_setup_events, METH_FASTCALL, "the events waits cross" },
    { "pending_input", fp_pending_input, METH_O, "the bytes readable on a descriptor (FIONREAD)" },
    { "attr", (PyCFunction)(void (*)(void))fp_attr, METH_FASTCALL, "o.name by the route of attrs.c" },
    { "handle", (PyCFunction)(void (*)(void))fp_handle, METH_FASTCALL, "acts on the messages it takes" },
    { "pump", (PyCFunction)(void (*)(void))fp_pump, METH_FASTCALL, "reads and acts on a connection" },
    { "handled", fp_handled, METH_O, "the messages acted on here so far" },
    { "counts", fp_counts, METH_O, "the I2C transfers, waits, PWM writes and promised writes acted on here" },
    MAILBOX_METHODS{ NULL, NULL, 0, NULL },
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT,
    "_riglockstep",
    "The lockstep session's per-cycle messages in C.",
    -1,
    methods,
    NULL,
    NULL,
    NULL,
    NULL,
};

PyMODINIT_FUNC PyInit__riglockstep(void)
{
    s_over_byte = PyUnicode_InternFromString("over_byte");
    s_pwm_config_changes = PyUnicode_InternFromString("pwm_config_changes");
    PyObject **names[] = { &s_steps_at, &s_ring,   &s_direct_pwm, &s_exported, &s_enabled, &s_period_ns,
                           &s_inversed, &s_epoch,  &s_anchor,     &s_cfg,      &s_div,     &s_period,
                           &s_accel_f,  &s_gyro_f, &s_addr,       &s_refill };
    const char *texts[] = { "_steps_at", "_ring",   "direct_pwm", "exported", "enabled", "period_ns",
                            "inversed",  "_epoch",  "_anchor",    "_cfg",     "_div",    "_period",
                            "_accel_f",  "_gyro_f", "_addr",      "refill" };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (!(*names[i] = PyUnicode_InternFromString(texts[i])))
            return NULL;
    if (!s_over_byte || !s_pwm_config_changes)
        return NULL;
    return PyModule_Create(&module);
}
