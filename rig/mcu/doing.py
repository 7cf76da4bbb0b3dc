"""What a hung firmware was doing: the loop its program counter is in, and the peripheral registers that
loop reads, in words ("polling UCSR0A in a loop at 0x001a4-0x001aa: waiting on USART0, bytes from a
receiver or a host"). A firmware waiting for its receiver, for EEPROM contents it likes, or for a
chip is the usual bring-up hang; the register it polls says which.

The loop is found in the flash image by the AVR instruction set's encodings (Atmel's "AVR Instruction
Set Manual"): from the stop's pc forward to the first backward branch (RJMP, BRBS/BRBC) whose target is
at or before it, or to RET; the I/O reads in it are IN, SBIS/SBIC and LDS, plus those of the functions
it calls (RCALL, CALL) up to their RET. Register addresses are the datasheets' data-space ones.
"""

from __future__ import annotations

from typing import Final

#: how far the loop search looks, in words (a polling loop is a few instructions)
LOOK: Final = 48
RET: Final = 0x9508
RETI: Final = 0x9518

#: fixed data-space addresses, the same on the ATmega328P and the ATmega2560
_COMMON: Final = {
    0x3F: ("EECR", "the EEPROM (its contents, or a write finishing)"),
    0x40: ("EEDR", "the EEPROM (its contents, or a write finishing)"),
    0x41: ("EEARL", "the EEPROM (its contents, or a write finishing)"),
    0x42: ("EEARH", "the EEPROM (its contents, or a write finishing)"),
    0x4D: ("SPSR", "the SPI"), 0x4E: ("SPDR", "the SPI"),
    0x78: ("ADCL", "the ADC"), 0x79: ("ADCH", "the ADC"), 0x7A: ("ADCSRA", "the ADC"),
    0xB9: ("TWSR", "the TWI"), 0xBB: ("TWDR", "the TWI"), 0xBC: ("TWCR", "the TWI"),
}


def register_names(mcu: str) -> dict[int, tuple[str, str]]:
    """Data-space address -> (register, what waiting on it means) for ``mcu``."""
    from rig.mcu.engine import PORTS, TIMERS, UARTS  # (the engine's tables; it imports this module)

    names = dict(_COMMON)
    for n, base in UARTS[mcu].items():
        waiting = f"USART{n}, bytes from a receiver or a host"
        names[base] = (f"UCSR{n}A", waiting)
        names[base + 6] = (f"UDR{n}", waiting)
    for port, pin in PORTS[mcu].items():
        names[pin] = (f"PIN{port}", f"port {port}'s input pins (a receiver's pulses, a switch)")
    for n, regs in TIMERS[mcu].items():
        names[regs[3]] = (f"TCNT{n}", f"timer {n}")
        names[0x35 + n] = (f"TIFR{n}", f"timer {n}")
    return names


def _reads(flash: bytes, start: int, end: int,
           whole: bool = False) -> tuple[list[int], list[int], int | None]:
    """Decodes words start..end: the data addresses read, the functions called, and the target of the
    first backward branch to at or before ``start`` (None: none before end or a RET; ``whole``: a
    function's body, read to its RET past its own loops)."""
    addrs: list[int] = []
    calls: list[int] = []
    k = start
    while k < end and 2 * k + 1 < len(flash):
        w = flash[2 * k] | flash[2 * k + 1] << 8
        nxt = flash[2 * k + 2] | flash[2 * k + 3] << 8 if 2 * k + 3 < len(flash) else 0
        size = 1
        if w & 0xF800 == 0xB000:  # IN Rd, A
            addrs.append(0x20 + ((w >> 5) & 0x30 | w & 0x0F))
        elif w & 0xFD00 == 0x9900:  # SBIC / SBIS A, b
            addrs.append(0x20 + (w >> 3 & 0x1F))
        elif w & 0xFE0F == 0x9000:  # LDS Rd, k
            addrs.append(nxt)
            size = 2
        elif w & 0xFE0F == 0x9200 or w & 0xFE0E == 0x940C:  # STS, JMP
            size = 2
        elif w & 0xFE0E == 0x940E:  # CALL k
            calls.append(((w >> 3 & 0x3E) | (w & 1)) << 16 | nxt)
            size = 2
        elif w & 0xF000 == 0xD000:  # RCALL k
            calls.append(k + 1 + ((w & 0xFFF) ^ 0x800) - 0x800)
        elif w & 0xF000 == 0xC000 or w & 0xF800 in (0xF000, 0xF400):  # RJMP k, BRBS/BRBC
            if w & 0xF000 == 0xC000:
                offset = ((w & 0xFFF) ^ 0x800) - 0x800
            else:
                offset = ((w >> 3 & 0x7F) ^ 0x40) - 0x40
            if k + 1 + offset <= start and not whole:
                return addrs, calls, k + 1 + offset
        elif w in (RET, RETI):
            return addrs, calls, None
        k += size
    return addrs, calls, None


def polling(flash: bytes, pc: int, mcu: str) -> str:
    """Words for what the firmware at byte address ``pc`` was doing ("" when nothing can be said)."""
    word = pc // 2
    addrs, calls, loop = _reads(flash, word, word + LOOK)
    if loop is not None and loop < word:  # (the loop's part before the pc)
        before, more, _ = _reads(flash, loop, word)
        addrs, calls = before + addrs, more + calls
    for target in calls[:4]:
        inside, _, _ = _reads(flash, target, target + LOOK, whole=True)
        addrs += inside
    names = register_names(mcu)
    seen = [names[a] for a in dict.fromkeys(addrs) if a in names]
    if not seen:
        return ""
    where = f"a loop at 0x{2 * loop:05x}" if loop is not None else f"the code at 0x{pc:05x}"
    regs = ", ".join(r for r, _ in seen)
    waits = "; ".join(dict.fromkeys(w for _, w in seen))
    return f"it was polling {regs} in {where}: waiting on {waits}"
