/* A chip core need (chip_core.h's chip_need) as the tuple of 13 ints the host-side producers take
 * (emulators/chips/board.py's Need). Shared by the emulators' module (fastcalls.c) and the lockstep fast
 * path (rig/lockstep/fastpath.c), which both hand needs to the same Python producers. Include after
 * Python.h and chip_core.h. */
#ifndef RIG_NEED_TUPLE_H
#define RIG_NEED_TUPLE_H

/* the need as a tuple of 13 ints (board.py's Need), built directly: no format string parsed per need */
static PyObject *need_tuple(const chip_need *n)
{
    unsigned long long v[13] = { n->chip,      n->keeps_all, n->anchor_mpu, n->osr,   n->t_thirds,
                                 n->hmc_start, n->count,     n->anchor,     n->epoch, n->t_ns,
                                 n->period_ns, n->anchor_ns, n->target_ns };
    PyObject *t = PyTuple_New(13);
    if (!t)
        return NULL;
    for (Py_ssize_t i = 0; i < 13; i++) {
        PyObject *x = PyLong_FromUnsignedLongLong(v[i]);
        if (!x) {
            Py_DECREF(t);
            return NULL;
        }
        PyTuple_SET_ITEM(t, i, x);
    }
    return t;
}

#endif
