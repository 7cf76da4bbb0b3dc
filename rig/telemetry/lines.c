/* The DUT's telemetry lines ("T t=... key=value ...") read into columns, in one pass over the bytes
 * (rig/telemetry/__init__.py says what is read; this is its work).
 *
 * Why C: the lines were read after each run by str.splitlines, str.split, str.partition and float() per
 * item: about 27 k instructions a line compiled by mypyc, 5 k per FC cycle of a lockstep flight at the
 * reference FC's 50 lines a second. The bytes are the DUT's and are not trusted; this reads them as the
 * Python did, decision for decision, with the text decoded as ASCII with "replace":
 *
 *  - lines end at \n, \r, \r\n, \v, \f, \x1c, \x1d and \x1e (str.splitlines on ASCII);
 *  - items are separated by runs of ASCII whitespace (str.split: those and \t, \x1f, space);
 *  - a byte above 0x7f is U+FFFD in the text: no line end, no whitespace, no '=', never part of a
 *    number or of a key read;
 *  - a value is converted as float() converts it: PyOS_string_to_double over the whole value (float's
 *    own conversion, infinities on overflow), or float() itself for a value with '_' or NUL. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

/* the columns read at most (t and the keys) */
#define MAX_KEYS 32
/* a value longer than this is not a number float() reads from a DUT's line: it goes to float() itself */
#define SHORT_VALUE 63

static int is_line_end(unsigned char c)
{
    return c == '\n' || c == '\r' || (c >= 0x0b && c <= 0x0c) || (c >= 0x1c && c <= 0x1e);
}

static int is_space(unsigned char c) { return c == ' ' || (c >= 0x09 && c <= 0x0d) || (c >= 0x1c && c <= 0x1f); }

/* a growing array of doubles */
typedef struct {
    double *v;
    Py_ssize_t n, cap;
} column;

static int push(column *c, double x)
{
    if (c->n == c->cap) {
        Py_ssize_t cap = c->cap ? 2 * c->cap : 256;
        double *v = PyMem_Realloc(c->v, (size_t)cap * sizeof *v);
        if (!v) {
            PyErr_NoMemory();
            return -1;
        }
        c->v = v;
        c->cap = cap;
    }
    c->v[c->n++] = x;
    return 0;
}

/* float(value) of value[0..n): 1 and *out; 0: float() would raise ValueError; -1: another error (raised) */
static int to_double(const char *value, Py_ssize_t n, double *out)
{
    int plain = n > 0 && n <= SHORT_VALUE;
    for (Py_ssize_t i = 0; i < n; i++) {
        unsigned char c = (unsigned char)value[i];
        if (c > 0x7f)
            return 0; /* U+FFFD: float() refuses it */
        if (c == '_' || c == 0)
            plain = 0;
    }
    if (plain) {
        char buf[SHORT_VALUE + 1];
        memcpy(buf, value, (size_t)n);
        buf[n] = 0;
        *out = PyOS_string_to_double(buf, NULL, NULL);
    } else {
        PyObject *s = PyUnicode_DecodeASCII(value, n, "strict");
        if (!s)
            return -1;
        PyObject *f = PyFloat_FromString(s);
        Py_DECREF(s);
        *out = f ? PyFloat_AS_DOUBLE(f) : -1.0;
        Py_XDECREF(f);
    }
    if (*out == -1.0 && PyErr_Occurred()) {
        if (!PyErr_ExceptionMatches(PyExc_ValueError))
            return -1;
        PyErr_Clear();
        return 0;
    }
    return 1;
}

typedef struct {
    const char *name[MAX_KEYS];
    Py_ssize_t len[MAX_KEYS];
    int count;
} keys;

static int key_index(const keys *k, const char *s, Py_ssize_t n)
{
    for (int i = 0; i < k->count; i++)
        if (k->len[i] == n && memcmp(k->name[i], s, (size_t)n) == 0)
            return i;
    return -1;
}

/* One "T " line's items after the "T ": 1 and values[] (NaN where missing, present[] says which);
 * 0: the line does not parse; -1: error (raised) */
static int read_items(const keys *k, const char *p, const char *end, double *values, int *present)
{
    const char *text[MAX_KEYS] = { 0 };
    Py_ssize_t text_len[MAX_KEYS] = { 0 };
    while (p < end) {
        while (p < end && is_space((unsigned char)*p))
            p++;
        if (p == end)
            break;
        const char *item = p;
        while (p < end && !is_space((unsigned char)*p))
            p++;
        const char *eq = memchr(item, '=', (size_t)(p - item));
        if (!eq)
            return 0;
        int i = key_index(k, item, eq - item);
        if (i >= 0) { /* a key given twice counts its last */
            text[i] = eq + 1;
            text_len[i] = p - (eq + 1);
        }
    }
    if (!text[0])
        return 0;
    for (int i = 0; i < k->count; i++) {
        present[i] = text[i] != NULL;
        values[i] = NAN;
        if (present[i]) {
            int got = to_double(text[i], text_len[i], &values[i]);
            if (got <= 0)
                return got;
        }
    }
    return 1;
}

static PyObject *as_bytearray(const column *c)
{
    return PyByteArray_FromStringAndSize((const char *)c->v, c->n * (Py_ssize_t)sizeof(double));
}

/* parse(text, clock_base_s, keys) -> (t, [column, ...], bad, first_nonfinite): see __init__.py */
static PyObject *parse(PyObject *self, PyObject *args)
{
    (void)self;
    Py_buffer text;
    double base;
    PyObject *names;
    if (!PyArg_ParseTuple(args, "y*dO!", &text, &base, &PyTuple_Type, &names))
        return NULL;
    PyObject *result = NULL, *nonfinite = NULL, *cols = NULL;
    column col[MAX_KEYS];
    memset(col, 0, sizeof col);
    keys k = { .count = (int)PyTuple_GET_SIZE(names) };
    if (k.count < 1 || k.count > MAX_KEYS) {
        PyErr_Format(PyExc_ValueError, "parse: 1 to %d keys (t first)", MAX_KEYS);
        goto done;
    }
    for (int i = 0; i < k.count; i++) {
        k.name[i] = PyUnicode_Check(PyTuple_GET_ITEM(names, i))
                        ? PyUnicode_AsUTF8AndSize(PyTuple_GET_ITEM(names, i), &k.len[i])
                        : NULL;
        if (!k.name[i]) {
            if (!PyErr_Occurred())
                PyErr_SetString(PyExc_TypeError, "parse: the keys are str");
            goto done;
        }
    }
    nonfinite = PyDict_New();
    if (!nonfinite)
        goto done;
    long long bad = 0;
    const char *p = text.buf, *end = p + text.len;
    while (p < end) {
        const char *line = p;
        while (p < end && !is_line_end((unsigned char)*p))
            p++;
        const char *line_end = p;
        if (p < end)
            p += (*p == '\r' && p + 1 < end && p[1] == '\n') ? 2 : 1;
        Py_ssize_t n = line_end - line;
        if (n > 0 && line[0] == '#') /* the DUT's messages on its telemetry port */
            continue;
        if (n < 2 || line[0] != 'T' || line[1] != ' ') {
            for (const char *c = line; c < line_end; c++)
                if (!is_space((unsigned char)*c)) {
                    bad++;
                    break;
                }
            continue;
        }
        double values[MAX_KEYS];
        int present[MAX_KEYS];
        int got = read_items(&k, line + 2, line_end, values, present);
        if (got < 0)
            goto done;
        double t = got ? values[0] - base : NAN;
        if (!isfinite(t)) {
            bad++;
            continue;
        }
        if (push(&col[0], t) < 0)
            goto done;
        for (int i = 1; i < k.count; i++) {
            double v = values[i];
            if (present[i] && !isfinite(v)) {
                v = NAN;
                PyObject *when = PyFloat_FromDouble(t);
                PyObject *had = when ? PyDict_SetDefault(nonfinite, PyTuple_GET_ITEM(names, i), when) : NULL;
                Py_XDECREF(when);
                if (!had)
                    goto done;
            }
            if (push(&col[i], v) < 0)
                goto done;
        }
    }
    cols = PyList_New(k.count - 1);
    if (!cols)
        goto done;
    for (int i = 1; i < k.count; i++) {
        PyObject *a = as_bytearray(&col[i]);
        if (!a)
            goto done;
        PyList_SET_ITEM(cols, i - 1, a);
    }
    PyObject *times = as_bytearray(&col[0]);
    if (times)
        result = Py_BuildValue("NOLO", times, cols, bad, nonfinite);
done:
    for (int i = 0; i < MAX_KEYS; i++)
        PyMem_Free(col[i].v);
    Py_XDECREF(cols);
    Py_XDECREF(nonfinite);
    PyBuffer_Release(&text);
    return result;
}

static PyMethodDef methods[] = {
    { "parse", parse, METH_VARARGS, "parse(text, clock_base_s, keys) -> (t, columns, bad, first_nonfinite)" },
    { NULL, NULL, 0, NULL },
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_rigtelemetry", NULL, -1, methods, NULL, NULL, NULL, NULL
};

PyMODINIT_FUNC PyInit__rigtelemetry(void) { return PyModule_Create(&module); }
