/* Runs an opcode no AVR has (0x0001: the reserved corner of the NOP/MOVW/MULS page), as a wild write into
 * the instruction stream would leave. */
int main(void)
{
    __asm__ volatile(".word 0x0001");
    for (;;) {
    }
}
