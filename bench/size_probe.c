/* Compiled for the M4 by bench_firmware.sh only: symbol sizes (nm -S) give the table sizes "tables aside" excludes. */
#include "calib.h"
#include "enc_hist.h"
#include "onset.h"

/* calib_t's derived buffers (f^-1, z_up, z_down), CALIB_DERIVED_MAX int32 each. */
char probe_calib_derived[sizeof(((calib_t *)0)->f_inv_buf) + sizeof(((calib_t *)0)->z_up_buf) +
                         sizeof(((calib_t *)0)->z_down_buf)];
/* The encoder history inside onset_t, ENC_HIST_LEN samples. */
char probe_enc_hist[sizeof(enc_hist_t)];
char probe_calib_t[sizeof(calib_t)];
char probe_onset_t[sizeof(onset_t)];
