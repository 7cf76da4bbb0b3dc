/* A test harness for the bridge's link code (not part of any bridge): reads wire bytes on stdin and
   decodes them as the bridge would ("down": what a host sends) or as a host would ("up"), printing each
   good message as a JSON line, then re-encoding it with link_frame to stdout-err... Usage:
     link_tool decode down|up     messages as JSON lines, then a line of counters
     link_tool reframe down|up    each good message framed again by the bridge's encoder, as hex lines
     link_tool MODE DIR IN OUT     the same reading the file IN, writing the file OUT (on a Cortex-M4
                                   under QEMU with semihosting, tests/bridge/tools.py)
   tests/bridge/test_link.py drives it against the host's codec. */
#define BRIDGE_MESSAGES_PRINT
#include <stdio.h>
#include <string.h>

#include "../core/link.h"

int main(int argc, char **argv)
{
    if ((argc != 3 && argc != 5) || (strcmp(argv[2], "down") && strcmp(argv[2], "up"))) {
        fprintf(stderr, "usage: link_tool decode|reframe down|up [IN OUT]\n");
        return 2;
    }
    if (argc == 5 && (!freopen(argv[3], "rb", stdin) || !freopen(argv[4], "w", stdout))) {
        fprintf(stderr, "link_tool: cannot open %s or %s\n", argv[3], argv[4]);
        return 2;
    }
    int reframe = strcmp(argv[1], "reframe") == 0;
    struct link_rx rx;
    link_rx_init(&rx, strcmp(argv[2], "up") == 0);
    int c;
    struct bridge_msg msg;
    while ((c = getchar()) != EOF) {
        if (!link_rx_byte(&rx, (uint8_t)c, &msg))
            continue;
        if (reframe) {
            uint8_t wire[LINK_WIRE_MAX];
            size_t n = link_frame(&msg, wire);
            for (size_t i = 0; i < n; i++)
                printf("%02x", wire[i]);
            printf("\n");
        } else {
            bridge_print(stdout, &msg);
        }
    }
    printf("{\"ok\": %lu, \"bad\": %lu, \"seq_gaps\": %lu, \"bad_cobs\": %lu, \"bad_crc\": %lu, \"bad_size\": %lu, "
           "\"bad_type\": %lu, \"bad_direction\": %lu, \"bad_overflow\": %lu}\n",
           (unsigned long)rx.ok, (unsigned long)rx.bad, (unsigned long)rx.seq_gaps, (unsigned long)rx.bad_cobs,
           (unsigned long)rx.bad_crc, (unsigned long)rx.bad_size, (unsigned long)rx.bad_type,
           (unsigned long)rx.bad_direction, (unsigned long)rx.bad_overflow);
    return 0;
}
