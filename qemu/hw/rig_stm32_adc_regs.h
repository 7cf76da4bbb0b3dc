/*
 * The STM32F4 ADCs' register map and bits (RM0090 section 13.13, table 71; RM0383 section 11.12) as data,
 * with the sampling times, the resolutions and the analog supply and internal channels' volts, for the ADC
 * model (rig_stm32_adc.c).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#ifndef RIG_STM32_ADC_REGS_H
#define RIG_STM32_ADC_REGS_H

#include "rig_stm32f4.h" /* (RigRegister) */

/* RM0090 13.13.1-13.13.15 (table 71, the ADC register map): each ADC's registers */
static const RigRegister adc_registers[] = {
    { 0x00, "SR", 0x00000000, 0x0000003F },    /* AWD, EOC, JEOC, JSTRT, STRT, OVR: rc_w0 */
    { 0x04, "CR1", 0x00000000, 0x07C0FFFF },   /* AWDCH ... DISCNUM, JAWDEN, AWDEN, RES, OVRIE */
    { 0x08, "CR2", 0x00000000, 0x7F7F0F03 },   /* ADON, CONT, DMA, DDS, EOCS, ALIGN, J/EXTSEL, J/EXTEN, J/SWSTART */
    { 0x0C, "SMPR1", 0x00000000, 0x07FFFFFF }, /* SMP10 ... SMP18 */
    { 0x10, "SMPR2", 0x00000000, 0x3FFFFFFF }, /* SMP0 ... SMP9 */
    { 0x14, "JOFR1", 0x00000000, 0x00000FFF }, { 0x18, "JOFR2", 0x00000000, 0x00000FFF },
    { 0x1C, "JOFR3", 0x00000000, 0x00000FFF }, { 0x20, "JOFR4", 0x00000000, 0x00000FFF },
    { 0x24, "HTR", 0x00000FFF, 0x00000FFF },   { 0x28, "LTR", 0x00000000, 0x00000FFF },
    { 0x2C, "SQR1", 0x00000000, 0x00FFFFFF }, /* SQ13 ... SQ16, L */
    { 0x30, "SQR2", 0x00000000, 0x3FFFFFFF }, /* SQ7 ... SQ12 */
    { 0x34, "SQR3", 0x00000000, 0x3FFFFFFF }, /* SQ1 ... SQ6 */
    { 0x38, "JSQR", 0x00000000, 0x003FFFFF }, /* JSQ1 ... JSQ4, JL */
    { 0x3C, "JDR1", 0x00000000, 0x00000000 },  { 0x40, "JDR2", 0x00000000, 0x00000000 },
    { 0x44, "JDR3", 0x00000000, 0x00000000 },  { 0x48, "JDR4", 0x00000000, 0x00000000 },
    { 0x4C, "DR", 0x00000000, 0x00000000 },
};
enum {
    R_SR,
    R_CR1,
    R_CR2,
    R_SMPR1,
    R_SMPR2,
    R_JOFR1,
    R_HTR = R_JOFR1 + 4,
    R_LTR,
    R_SQR1,
    R_SQR2,
    R_SQR3,
    R_JSQR,
    R_JDR1,
    R_DR = R_JDR1 + 4,
    R_REGS
};

/* 13.13.16-13.13.18: the common registers, from 0x300 */
static const RigRegister common_registers[] = {
    { 0x00, "CSR", 0x00000000, 0x00000000 }, /* the three SRs, read only */
    { 0x04, "CCR", 0x00000000, 0x00C3EF1F }, /* MULTI, DELAY, DDS, DMA, ADCPRE, VBATE, TSVREFE */
    { 0x08, "CDR", 0x00000000, 0x00000000 }, /* multi mode's data: not modelled */
};
enum { C_CSR, C_CCR, C_CDR };

#define SR_AWD (1u << 0)
#define SR_EOC (1u << 1)
#define SR_JEOC (1u << 2)
#define SR_JSTRT (1u << 3)
#define SR_STRT (1u << 4)
#define SR_OVR (1u << 5)
#define CR1_AWDCH 0x1Fu
#define CR1_EOCIE (1u << 5)
#define CR1_AWDIE (1u << 6)
#define CR1_JEOCIE (1u << 7)
#define CR1_SCAN (1u << 8)
#define CR1_AWDSGL (1u << 9)
#define CR1_JAUTO (1u << 10)
#define CR1_JAWDEN (1u << 22)
#define CR1_AWDEN (1u << 23)
#define CR1_RES_SHIFT 24
#define CR1_OVRIE (1u << 26)
#define CR2_ADON (1u << 0)
#define CR2_CONT (1u << 1)
#define CR2_DMA (1u << 8)
#define CR2_EOCS (1u << 10)
#define CR2_ALIGN (1u << 11)
#define CR2_JSWSTART (1u << 22)
#define CR2_SWSTART (1u << 30)
#define CCR_MULTI 0x1Fu
#define CCR_ADCPRE_SHIFT 16
#define CCR_VBATE (1u << 22)
#define CCR_TSVREFE (1u << 23)

#define ADC_UNITS 3
#define ADC_INPUTS 16 /* the external channels */
#define ADC_CHANNELS 19
#define VDDA_UV 3300000u   /* the board's analog supply and reference */
#define TEMP_25C_UV 760000 /* DS8626 table 68 (temperature sensor): V25 */
#define VREFINT_UV 1210000 /* DS8626 table 69 (internal reference voltage): typical */
#define VBAT_UV 3000000    /* the backup battery: a fixed 3.0 V coin cell */

/* 13.13.4, 13.13.5: SMPx, the sampling time in ADC clock cycles; 13.13.2: RES, the bits (conversion cycles) */
static const uint16_t sampling_cycles[8] = { 3, 15, 28, 56, 84, 112, 144, 480 };
static const uint8_t resolution_bits[4] = { 12, 10, 8, 6 };

#endif
