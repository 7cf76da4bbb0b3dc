/* The transfer log's row (Handler.i2c_log, run.mcap's /i2c) for a transfer the fast path made (included
 * by fastpath.c): (t_ns, first address, the bytes written, the bytes read, status), as the handler
 * appends it. Built item by item: Py_BuildValue parses its format string at every transfer (its own
 * instructions were under 1 k of an FC cycle in a profile). Kept apart from fastpath.c for its size. */

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
    PyObject *items[5] = { PyLong_FromUnsignedLongLong(t), PyLong_FromUnsignedLong(m[0].addr), w,
                           PyBytes_FromStringAndSize((const char *)out, (Py_ssize_t)got),
                           PyLong_FromUnsignedLong(status) };
    PyObject *row = NULL;
    if (items[0] && items[1] && items[3] && items[4] && (row = PyTuple_New(5)))
        for (int i = 0; i < 5; i++)
            PyTuple_SET_ITEM(row, i, items[i]);
    if (!row) {
        for (int i = 0; i < 5; i++)
            Py_XDECREF(items[i]);
        return -1;
    }
    int bad = PyList_Append(s->i2c_log, row);
    Py_DECREF(row);
    return bad ? -1 : 0;
}
