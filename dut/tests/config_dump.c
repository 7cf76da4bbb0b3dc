/* config_dump conf FILE | image FILE: the configuration the Linux parser (a config file) or the AVR's
   EEPROM loader (an image) makes of its input, as "key = values" lines for every number key, after a
   "status = ..." line. Built in single precision like the AVR; tests/dut/test_eeprom_image.py holds the
   two against each other for every library scenario. */
#include <stdio.h>
#include <string.h>

#include "config.h"
#include "config_image.h"
#include "config_keys.h"

static void dump(const fc_config *c)
{
#define PRINT_D(name, n)                                          \
    do {                                                          \
        printf(#name " =");                                       \
        for (int j = 0; j < (n); j++)                             \
            printf(" %.9g", (double)((const real *)&c->name)[j]); \
        printf("\n");                                             \
    } while (0)
#define PRINT_I(name, n) printf(#name " = %d\n", *(const int *)&c->name)
#define PRINT_S(name, n)
#define FC_KEY(name, kind, n, lo, hi) PRINT_##kind(name, n);
    FC_CONFIG_KEYS(FC_KEY)
#undef FC_KEY
}

int main(int argc, char **argv)
{
    if (argc != 3 || (strcmp(argv[1], "conf") != 0 && strcmp(argv[1], "image") != 0)) {
        fprintf(stderr, "usage: config_dump conf|image FILE\n");
        return 2;
    }
    fc_config c;
    config_defaults(&c);
    if (argv[1][0] == 'c') {
        char err[256];
        if (config_load(&c, argv[2], err, sizeof err) < 0) {
            printf("status = %s\n", err);
            return 1;
        }
        printf("status = ok\n");
    } else {
        static uint8_t img[4096];
        FILE *f = fopen(argv[2], "rb");
        if (!f) {
            fprintf(stderr, "config_dump: cannot open %s\n", argv[2]);
            return 2;
        }
        size_t n = fread(img, 1, sizeof img, f);
        fclose(f);
        int st = config_from_image(&c, img, (unsigned)n);
        printf("status = %s\n", st == FC_IMAGE_OK ? "ok" : fc_image_why(st));
    }
    dump(&c);
    return 0;
}
