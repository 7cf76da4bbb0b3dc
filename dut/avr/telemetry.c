/* The telemetry line (telemetry.h), built without printf (uart0.h's line helpers). */
#include "telemetry.h"

#include "board.h"
#include "uart0.h"

uint8_t telemetry_line(char *buf, uint16_t wraps, uint32_t ticks, const flight *fl, const tel_counters *k)
{
    line l = { buf, 0, TELEMETRY_LINE - 1 };
    const real deg = 180 / M_PI;
    /* seconds and 0.1 ms of wraps * 2^32 + ticks, in 32 bits (a 64-bit division costs thousands of
       cycles): 2^32 ticks are 2147 s and 967296 ticks */
    uint32_t sec = ticks / TICKS_PER_S, rem = ticks % TICKS_PER_S;
    for (uint16_t w = wraps; w; w--) {
        sec += 2147;
        rem += 967296;
        if (rem >= TICKS_PER_S) {
            rem -= TICKS_PER_S;
            sec++;
        }
    }
    line_str(&l, "T t=");
    line_int(&l, (int32_t)sec);
    line_str(&l, ".");
    line_fixed_digits(&l, (uint16_t)(rem / (TICKS_PER_S / 10000)), 4);
    line_str(&l, " roll=");
    line_fixed(&l, fl->att.roll * deg, 3);
    line_str(&l, " pitch=");
    line_fixed(&l, fl->att.pitch * deg, 3);
    line_str(&l, " yaw=");
    line_fixed(&l, fl->att.yaw * deg, 3);
    line_str(&l, " alt=");
    line_fixed(&l, fl->altf.h, 3);
    line_str(&l, " armed=");
    line_int(&l, fl->armed);
    line_str(&l, " rc=");
    line_int(&l, fl->rc_ok);
    line_str(&l, " gyro_fault=");
    line_int(&l, fl->gyro_fault);
    line_str(&l, " loop_us=");
    line_int(&l, (int32_t)(k->loop_ticks / 2));
    line_str(&l, " max_us=");
    line_int(&l, (int32_t)(k->max_ticks / 2));
    line_str(&l, " overruns=");
    line_int(&l, (int32_t)k->overruns);
    line_str(&l, " cfg=");
    line_str(&l, k->cfg);
    line_str(&l, " twi_err=");
    line_int(&l, (int32_t)k->twi.nacks + k->twi.timeouts + k->twi.bus_errors);
    line_str(&l, " twi_rec=");
    line_int(&l, k->twi.recoveries);
    line_str(&l, " sbus_ok=");
    line_int(&l, k->sbus.frames);
    line_str(&l, " sbus_bad=");
    line_int(&l, (int32_t)k->sbus.bad_frames + k->sbus.byte_errors);
    line_str(&l, " tel_drop=");
    line_int(&l, k->tel_dropped);
    buf[l.n++] = '\n';
    return l.n;
}
