/* A reply to the DUT (included by fastpath.c, after mailbox.c): through its mailbox when it has one,
 * else on its socket, waiting for room there at most protocol.REPLY_TIMEOUT_S a send (the socket's
 * SO_SNDTIMEO). Kept apart from fastpath.c for its size. */

/* rig.protocol.RepliesUnread with its message, the connection shut (Conn.send's rule, rig/connection.py:
 * the socket's send timeout ran out, so the DUT has left a socket buffer of replies unread) */
static void replies_unread(int fd)
{
    shutdown(fd, SHUT_RDWR);
    PyObject *protocol = PyImport_ImportModule("rig.protocol");
    PyObject *kind = protocol ? PyObject_GetAttrString(protocol, "RepliesUnread") : NULL;
    PyObject *why = kind ? PyObject_GetAttrString(protocol, "REPLIES_UNREAD") : NULL;
    if (kind && why)
        PyErr_SetObject(kind, why);
    Py_XDECREF(protocol);
    Py_XDECREF(kind);
    Py_XDECREF(why);
}

/* send() of what is left; when the socket has no room at once, the wait for it with the GIL released
 * (Python's own sendall does the same: sessions that run in threads of one process, a sweep's or the
 * service's, go on while this one waits) */
static ssize_t send_some(int fd, const uint8_t *p, size_t n)
{
    ssize_t k = send(fd, p, n, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (k >= 0 || (errno != EAGAIN && errno != EWOULDBLOCK))
        return k;
    PyThreadState *saved = PyEval_SaveThread();
    k = send(fd, p, n, MSG_NOSIGNAL);
    int e = errno;
    PyEval_RestoreThread(saved);
    errno = e;
    return k;
}

/* 1: sent; 0: the DUT is gone (the loop sees its exit, Session.send); -1: raised (a signal's handler, or
 * the DUT not taking its replies). A signal that interrupts the send runs its Python handler here: the
 * rig's SIGTERM must not wait on a DUT that has stopped reading. */
static int send_all(fast_state *s, int fd, const uint8_t *p, size_t n)
{
    mbox_slot *mb = mbox_find(s->mboxes, fd);
    if (mb)
        return mbox_put(mb, p, n); /* (no room: a DUT that does not read its replies; it is stalled) */
    while (n) {
        ssize_t k = send_some(fd, p, n);
        if (k < 0) {
            if (errno == EINTR) {
                if (PyErr_CheckSignals() < 0)
                    return -1;
                continue;
            }
            if (errno == EAGAIN || errno == EWOULDBLOCK) {
                replies_unread(fd);
                return -1;
            }
            return 0;
        }
        p += k, n -= (size_t)k;
    }
    return 1;
}
