/* File-backed flash port for the desktop virtual board: both slots in one file, NOR semantics. */
#ifndef PSS_FLASH_FILE_H
#define PSS_FLASH_FILE_H

#include <stdint.h>
#include <stdio.h>
#include "storage/pss_store.h"

typedef struct {
    FILE *f;
    uint32_t slot_size;
    pss_flash_t port;
} pss_file_t;

/* Why pss_file_open failed. */
enum {
    PSS_FILE_OK = 0,
    PSS_FILE_ERR_OPEN = -1,      /* cannot open or create it (errno says why) */
    PSS_FILE_ERR_LOCKED = -2,    /* another process holds it: one board per flash file */
    PSS_FILE_ERR_NOT_IMAGE = -3, /* exists but is not a regular file of 2 * slot_size bytes */
};

/* Open (creating, erased to 0xFF, if absent) a file of 2 * slot_size bytes and hold an
 * exclusive advisory lock (flock) on it until pss_file_close or exit, so a second board
 * process on the same file is refused instead of both committing "generation N" and one
 * losing its table. An existing file of another size or kind is never written (a user's
 * file given as the flash file by mistake stays intact). PSS_FILE_OK or a PSS_FILE_ERR_*. */
int pss_file_open(pss_file_t *ff, const char *path, uint32_t slot_size);

void pss_file_close(pss_file_t *ff);

#endif /* PSS_FLASH_FILE_H */
