/* Compiled for the M4 by bench_firmware.sh only: symbol sizes (nm -S) break the image's RAM down. */
#include "calib.h"
#include "enc_hist.h"
#include "psa_loop.h"

char probe_calib_t[sizeof(calib_t)];
char probe_enc_hist[sizeof(enc_hist_t)];
char probe_psa_loop_t[sizeof(psa_loop_t)];
char probe_b_online_t[sizeof(b_online_t)];
char probe_f_online_t[sizeof(f_online_t)];
