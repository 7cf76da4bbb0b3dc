/*
 * The sysfs PWM class: what its attributes accept. Part of rigshim.c (one translation unit): see its
 * top comment.
 */

static int parse_u64(const char *buf, size_t n, uint64_t *out)
{
    char s[32];
    if (n == 0 || n >= sizeof s)
        return -1;
    memcpy(s, buf, n);
    s[n] = 0;
    if (s[n - 1] == '\n')
        s[--n] = 0; /* sysfs accepts one trailing newline, as echo writes */
    if (n == 0 || s[0] == '-' || s[0] == '+' || s[0] == ' ')
        return -1;
    char *end;
    errno = 0;
    unsigned long long v = strtoull(s, &end, 0);
    if (errno || *end)
        return -1;
    *out = v;
    return 0;
}

static int streq_nl(const char *buf, size_t n, const char *word)
{
    size_t w = strlen(word);
    return (n == w || (n == w + 1 && buf[w] == '\n')) && memcmp(buf, word, w) == 0;
}
