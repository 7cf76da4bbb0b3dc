/* A firmware that locks up: with FAULTMASK set (execution priority -1) an undefined instruction's
   UsageFault cannot escalate to a HardFault (ARMv7-M B1.5.15, "Unrecoverable exception cases"), and
   the core locks up. QEMU 7.2 does not model lockup: it stops with a message and its registers. */
int main(void)
{
    __asm volatile("cpsid f\n udf #0");
    return 0;
}
