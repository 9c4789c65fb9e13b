/* File-backed flash port for the desktop virtual board: both slots in one file, NOR semantics. */
#ifndef PSS_FLASH_FILE_H
#define PSS_FLASH_FILE_H

#include <stdint.h>
#include <stdio.h>
#include "pss_store.h"

typedef struct {
    FILE *f;
    uint32_t slot_size;
    pss_flash_t port;
} pss_file_t;

/* Open (creating, erased to 0xFF, if absent) a file of 2 * slot_size bytes. 0 on success. */
int pss_file_open(pss_file_t *ff, const char *path, uint32_t slot_size);

void pss_file_close(pss_file_t *ff);

#endif /* PSS_FLASH_FILE_H */
