/* The configuration as an EEPROM image (the AVR has no file system): its layout is generated from the
   one key table (config_keys.h), and scenarios/eeprom.py writes the same layout from a scenario's [fc]
   table. Little-endian, as the AVR stores words:

     0  u16 magic 0x4346 ("FC")
     2  u16 layout: CRC-16 of the key table's signature ("name:KindCount;" per key, FC_IMAGE_SIGNATURE),
        so an image written for another key table is refused rather than misread
     4  u8  profile (FC_PROFILES index; 0xFF: none), applied before the keys
     5  u8  number of keys in the table
     6  presence bitmap, one bit per key in table order (bit k%8 of byte k/8): set keys override defaults
     .. values of every number key in table order: kind D as `count` float32, kind I as int32 (path keys,
        kind S, are Linux's and take no room)
     .. u16 CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of everything before it

   A value outside its key's range, or ctrl_rate_hz above est_rate_hz, refuses the image as the Linux
   parser refuses the file. A refused image leaves the defaults (flash), and the firmware says why. */
#ifndef CONFIG_IMAGE_H
#define CONFIG_IMAGE_H

#include <stdint.h>

#include "config.h"
#include "config_keys.h"

#define FC_IMAGE_MAGIC 0x4346u

#define FC_IMAGE_KEY_COUNT_(name, kind, n, lo, hi) +1
#define FC_IMAGE_NKEYS (0 FC_CONFIG_KEYS(FC_IMAGE_KEY_COUNT_))
#define FC_IMAGE_VALUE_D(n) (4 * (n))
#define FC_IMAGE_VALUE_I(n) 4
#define FC_IMAGE_VALUE_S(n) 0
#define FC_IMAGE_KEY_SIZE_(name, kind, n, lo, hi) +FC_IMAGE_VALUE_##kind(n)
#define FC_IMAGE_VALUES (0 FC_CONFIG_KEYS(FC_IMAGE_KEY_SIZE_))
#define FC_IMAGE_HEADER (6 + (FC_IMAGE_NKEYS + 7) / 8)
#define FC_IMAGE_SIZE (FC_IMAGE_HEADER + FC_IMAGE_VALUES + 2)

enum fc_image_status {
    FC_IMAGE_OK = 0,
    FC_IMAGE_BLANK = 1,   /* erased (0xFF) or never written */
    FC_IMAGE_MAGIC_BAD,   /* not an image */
    FC_IMAGE_LAYOUT_BAD,  /* written for another key table */
    FC_IMAGE_CRC_BAD,     /* corrupt */
    FC_IMAGE_VALUE_BAD,   /* a value outside its key's range (or not finite) */
    FC_IMAGE_PROFILE_BAD, /* no such profile */
    FC_IMAGE_RATES_BAD,   /* ctrl_rate_hz above est_rate_hz */
};

/* each key's index in the table (and in the presence bits): FC_KEY_INDEX_rate_kp, ... */
#define FC_IMAGE_KEY_INDEX_(name, kind, n, lo, hi) FC_KEY_INDEX_##name,
enum fc_key_index { FC_CONFIG_KEYS(FC_IMAGE_KEY_INDEX_) FC_KEY_INDEX_COUNT };

uint16_t fc_crc16(const uint8_t *p, unsigned n, uint16_t crc); /* CCITT-FALSE step; start with 0xFFFF */
uint16_t fc_image_layout(void);                                /* the CRC-16 of the signature */
/* *c gets the defaults, then the image's profile and keys when the whole image is good; else it keeps
   the defaults. Returns an fc_image_status. */
int config_from_image(fc_config *c, const uint8_t *img, unsigned n);
const char *fc_image_why(int status);
/* Of an image config_from_image took: whether it sets this key, and whether it names a profile */
int fc_image_sets(const uint8_t *img, enum fc_key_index key);
int fc_image_has_profile(const uint8_t *img);

#endif
