/* Calls through a pointer past the end of the program (a corrupted function pointer). */
#include <stdint.h>

typedef void (*fn)(void);
volatile uint16_t target = 0x3000; /* a word address: byte 0x6000, past this small program */

int main(void)
{
    ((fn)target)();
    for (;;) {
    }
}
