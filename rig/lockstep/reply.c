/* A reply to the DUT (included by fastpath.c, after mailbox.c): through its mailbox when it has one,
 * else on its socket, never waiting on that socket for good. Kept apart from fastpath.c for its size. */

/* rig.protocol.RepliesUnread with its message, the connection shut (Conn.send's rule, rig/connection.py:
 * the socket's send timeout ran out, so the DUT has left a socket buffer of replies unread) */
static void replies_unread(int fd)
{
    shutdown(fd, SHUT_RDWR);
    PyObject *protocol = PyImport_ImportModule("rig.protocol");
    PyObject *kind = protocol ? PyObject_GetAttrString(protocol, "RepliesUnread") : NULL;
    PyObject *why = protocol ? PyObject_GetAttrString(protocol, "REPLIES_UNREAD") : NULL;
    if (kind && why)
        PyErr_SetObject(kind, why);
    Py_XDECREF(protocol);
    Py_XDECREF(kind);
    Py_XDECREF(why);
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
        ssize_t k = send(fd, p, n, MSG_NOSIGNAL);
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
