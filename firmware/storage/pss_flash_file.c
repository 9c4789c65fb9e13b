/* File-backed flash port: each erase/program is flushed so a killed process leaves a real partial write. */
/* fdopen, flock: POSIX and BSD calls outside -std=c11 */
#define _DEFAULT_SOURCE
#include "storage/pss_flash_file.h"

#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

static int file_erase(void *ctx, uint8_t slot)
{
    pss_file_t *ff = ctx;
    uint8_t ones[256];
    memset(ones, 0xFF, sizeof(ones));
    if (slot > 1 || fseek(ff->f, (long)slot * (long)ff->slot_size, SEEK_SET) != 0)
        return -1;
    for (uint32_t done = 0; done < ff->slot_size;) {
        size_t n = ff->slot_size - done < sizeof(ones) ? ff->slot_size - done : sizeof(ones);
        if (fwrite(ones, 1, n, ff->f) != n)
            return -1;
        done += (uint32_t)n;
    }
    return fflush(ff->f) == 0 ? 0 : -1;
}

static int file_read(void *ctx, uint8_t slot, uint32_t off, uint8_t *out, uint32_t len)
{
    pss_file_t *ff = ctx;
    if (slot > 1 || off > ff->slot_size || len > ff->slot_size - off)
        return -1;
    if (fseek(ff->f, (long)slot * (long)ff->slot_size + (long)off, SEEK_SET) != 0)
        return -1;
    return fread(out, 1, len, ff->f) == len ? 0 : -1;
}

static int file_program(void *ctx, uint8_t slot, uint32_t off, const uint8_t *data, uint32_t len)
{
    pss_file_t *ff = ctx;
    uint8_t cur[256];
    /* Read-AND-write so the file behaves like NOR flash (bits only clear). */
    for (uint32_t done = 0; done < len;) {
        uint32_t n = len - done < sizeof(cur) ? len - done : (uint32_t)sizeof(cur);
        if (file_read(ctx, slot, off + done, cur, n) != 0)
            return -1;
        for (uint32_t i = 0; i < n; i++)
            cur[i] &= data[done + i];
        if (fseek(ff->f, (long)slot * (long)ff->slot_size + (long)(off + done), SEEK_SET) != 0 ||
            fwrite(cur, 1, n, ff->f) != n)
            return -1;
        done += n;
    }
    return fflush(ff->f) == 0 ? 0 : -1;
}

int pss_file_open(pss_file_t *ff, const char *path, uint32_t slot_size)
{
    memset(ff, 0, sizeof(*ff));
    ff->slot_size = slot_size;
    /* Open without truncating or creating first: the lock and the size are checked before a
     * single byte is written. Never through a symbolic link (O_NOFOLLOW): the image is written
     * in place, and a link would aim those writes at whatever it names. */
    int fd = open(path, O_RDWR | O_CREAT | O_NOFOLLOW, 0644);
    if (fd < 0)
        return PSS_FILE_ERR_OPEN;
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
        int e = errno;
        close(fd);
        errno = e;
        return e == EWOULDBLOCK ? PSS_FILE_ERR_LOCKED : PSS_FILE_ERR_OPEN;
    }
    struct stat st;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) ||
        (st.st_size != 0 && (uint64_t)st.st_size != 2ull * slot_size)) {
        close(fd);
        return PSS_FILE_ERR_NOT_IMAGE;
    }
    const int fresh = st.st_size == 0; /* just created (or an empty file): erase both slots */
    ff->f = fdopen(fd, "r+b");
    if (!ff->f) {
        close(fd);
        return PSS_FILE_ERR_OPEN;
    }
    ff->port.ctx = ff;
    if (fresh && (file_erase(ff, 0) != 0 || file_erase(ff, 1) != 0)) {
        pss_file_close(ff);
        return PSS_FILE_ERR_OPEN;
    }
    ff->port.slot_size = slot_size;
    ff->port.erase = file_erase;
    ff->port.program = file_program;
    ff->port.read = file_read;
    ff->port.ctx = ff;
    return PSS_FILE_OK;
}

void pss_file_close(pss_file_t *ff)
{
    if (ff->f)
        fclose(ff->f);
    ff->f = NULL;
}
