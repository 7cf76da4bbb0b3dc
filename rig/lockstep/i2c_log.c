/* The transfer log's row (Handler.i2c_log, run.mcap's /i2c) for a transfer the fast path made (included
 * by fastpath.c): an I2CRecord (scenarios/result.py: sim time, first address, register, the bytes
 * written, the bytes read, completed), as the handler appends it, and as the run's result keeps it: the
 * log is the result's list, not converted after the run (a Python frame per row cost 1.4 k instructions
 * per FC cycle). Built item by item: Py_BuildValue parses its format string at every transfer. Kept
 * apart from fastpath.c for its size. */

/* 0, or -1 (raised); nothing is appended once the log holds I2C_LOG_CAP rows */
static int log_transfer(fast_state *s, uint64_t t, const struct rig_i2c_msg *m, uint32_t n, const uint8_t *const *data,
                        const uint8_t *out, size_t got, uint16_t status)
{
    if (PyList_GET_SIZE(s->i2c_log) >= I2C_LOG_CAP)
        return 0;
    size_t wrote = 0;
    for (uint32_t i = 0; i < n; i++)
        wrote += m[i].flags & I2C_M_RD ? 0 : m[i].len;
    PyObject *w = PyBytes_FromStringAndSize(NULL, (Py_ssize_t)wrote);
    if (!w)
        return -1;
    wrote = 0;
    for (uint32_t i = 0; i < n; i++)
        if (!(m[i].flags & I2C_M_RD)) {
            memcpy(PyBytes_AS_STRING(w) + wrote, data[i], m[i].len);
            wrote += m[i].len;
        }
    PyObject *reg = wrote ? PyLong_FromLong(PyBytes_AS_STRING(w)[0] & 0xff) : Py_NewRef(Py_None);
    PyObject *items[6] = { PyLong_FromUnsignedLongLong(t),
                           PyLong_FromUnsignedLong(m[0].addr),
                           reg,
                           w,
                           PyBytes_FromStringAndSize((const char *)out, (Py_ssize_t)got),
                           Py_NewRef(status ? Py_False : Py_True) };
    PyObject *row = NULL; /* (a tuple's subclass: made as tuple.__new__ makes it) */
    if (items[0] && items[1] && items[2] && items[4] && (row = s->record->tp_alloc(s->record, 6)))
        for (int i = 0; i < 6; i++)
            PyTuple_SET_ITEM(row, i, items[i]);
    if (!row) {
        for (int i = 0; i < 6; i++)
            Py_XDECREF(items[i]);
        return -1;
    }
    /* nothing in a row can lead back to it: the collector need not follow it (an exact tuple of such items
     * it leaves after a first look; a subclass's it would walk at every full collection, a growing log's
     * whole length: 79 k instructions per FC cycle where 61 k were without the log's rows) */
    PyObject_GC_UnTrack(row);
    int bad = PyList_Append(s->i2c_log, row);
    Py_DECREF(row);
    return bad ? -1 : 0;
}
