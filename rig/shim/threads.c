/*
 * The DUT's threads: pthread_create. In lockstep a thread asked for with a real-time policy is created
 * with its creator's (priorities.c records the request). Part of rigshim.c (one translation unit):
 * see its top comment.
 */

EXPORT int pthread_create(pthread_t *thread, const pthread_attr_t *attr, void *(*start)(void *), void *arg)
{
    pthread_attr_t copy;
    if (lockstep_attr(attr, &copy))
        attr = &copy;
    return LOAD(pthread_create)(thread, attr, start, arg);
}
