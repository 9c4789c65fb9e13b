/* Virtual board: the desktop build of core + link as a process, over stdio, a TCP socket or a pty. */
#define _DEFAULT_SOURCE /* clock_gettime, posix_openpt and friends under -std=c11 */
#define _XOPEN_SOURCE 600
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "psb_config.h"
#include "storage/pss_flash_file.h"
#include "storage/pss_flash_sim.h"
#include "link/psl_link.h"

enum {
    VB_SLOT_SIZE = 128 * 1024, /* as one STM32F405 sector 10/11 */
    VB_TICKS_MAX_PER_WAKE = 200, /* after a stall, catch up at most this many ticks at once */
    VB_MAX_HOSTS = 4,            /* --listen: hosts connected at once (like a UART and a USB port) */
};

/* One host port of --listen: its own frame parser and replay window, as a board with a
 * UART and a USB port keeps per port. The board state (tables, upload session, mode) is
 * shared: that is what two hosts contend for. */
typedef struct {
    int fd;                      /* -1: free */
    psf_parser_t parser;
    uint16_t last_seq;
} vb_port_t;

static psl_t board;
static int out_fd = 1;
static volatile sig_atomic_t stop;

static void on_signal(int sig)
{
    (void)sig;
    stop = 1;
}

static void write_all(void *ctx, const uint8_t *frame, size_t len)
{
    (void)ctx;
    while (len > 0) {
        ssize_t n = write(out_fd, frame, len);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            return; /* host gone: drop, as a UART would */
        frame += n;
        len -= (size_t)n;
    }
}

static uint64_t now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* The board clock of a serve loop. Free-running (the default): board time = time_scale x wall
 * time since start; after a stall of more than VB_TICKS_MAX_PER_WAKE ticks the backlog is dropped
 * (board time jumps), as on a board whose loop overran.
 * Lock-step (lead_us > 0, --lockstep-ms, for closed-loop simulations): while the excitation runs,
 * the board runs at most lead_us of board time past the later of the excitation's start and the
 * last marker observation, and wall time spent waiting or stalled is not counted, so no tick is
 * dropped. A host that lags (a loaded machine) then slows the board down instead of sending
 * observations that arrive after the encoder history (ENC_HIST_LEN) or the onset timeout has
 * moved on: what a simulated instrument needs to give the same onsets at any machine load. */
typedef struct {
    uint64_t wall0_us, held_us;  /* start; wall time not counted (lock-step waits and stalls) */
    uint64_t ticks, tick_ns;
    double time_scale;
    uint32_t lead_us;            /* 0: free-running */
    uint32_t exc_start_us;       /* board time the excitation started (lock-step reference) */
    bool in_exc;
    int32_t q_q16;               /* ideal motor: q measured = last set-point */
} vb_clock_t;

static void vb_clock_init(vb_clock_t *c, uint32_t tick_hz, double time_scale, uint32_t lead_us)
{
    *c = (vb_clock_t){.wall0_us = now_us(), .tick_ns = 1000000000ull / tick_hz, .time_scale = time_scale,
                      .lead_us = lead_us};
}

/* Board time up to which lock-step lets the board run. */
static uint32_t vb_lockstep_limit_us(const vb_clock_t *c)
{
    uint32_t ref = c->exc_start_us;
    if ((int32_t)(board.last_obs_us - ref) > 0)
        ref = board.last_obs_us;
    return ref + c->lead_us;
}

/* Run the ticks due at the wall clock's now, then one background step (an on-line B sample
 * between ticks, as the M4 images do). */
static void vb_run_due(vb_clock_t *c)
{
    uint64_t wall = now_us() - c->wall0_us;
    uint64_t due = (uint64_t)((double)(wall - c->held_us) * 1000.0 * c->time_scale / (double)c->tick_ns);
    bool held = false;
    for (int k = 0; c->ticks < due && k < VB_TICKS_MAX_PER_WAKE; k++, c->ticks++) {
        uint32_t t_us = (uint32_t)(c->ticks * c->tick_ns / 1000u);
        bool exc = board.loop.mode == PSA_MODE_EXCITATION;
        if (exc && !c->in_exc)
            c->exc_start_us = t_us;
        c->in_exc = exc;
        if (c->lead_us && exc && (int32_t)(t_us - vb_lockstep_limit_us(c)) > 0) {
            held = true;
            break;
        }
        c->q_q16 = psl_tick(&board, t_us, c->q_q16);
    }
    (void)psl_background(&board);
    if (due <= c->ticks + (held ? 0u : VB_TICKS_MAX_PER_WAKE))
        return;
    if (c->lead_us) /* do not count the wall time the board did not run: board time = ticks */
        c->held_us = wall - (uint64_t)((double)c->ticks * (double)c->tick_ns / 1000.0 / c->time_scale);
    else
        c->ticks = due; /* drop the backlog rather than replay a long stall */
}

static void usage(void)
{
    fprintf(stderr,
            "usage: ps_vboard [--flash FILE] [--stdio | --listen PORT | --pty] [--tick-hz HZ]\n"
            "  --flash FILE   file-backed A/B slots (2 x 128 KiB), kept across runs; default: RAM\n"
            "  --stdio        frames on stdin/stdout (default)\n"
            "  --listen PORT  TCP on 127.0.0.1:PORT, up to 4 hosts at once (prints 'listening PORT')\n"
            "  --pty          a pseudo-terminal (prints 'pty /dev/pts/N')\n"
            "  --tick-hz HZ   control tick rate, default 1000\n"
            "  --upload-timeout-ms MS  a table upload session silent this long is free again, default 5000\n"
            "  --time-scale X board clock runs X times the wall clock (simulation only), default 1\n"
            "  --lockstep-ms L  simulation only: during the excitation the board runs at most L ms of\n"
            "                 board time past the last marker observation, waiting for a lagging host\n"
            "                 (its onsets then do not depend on the machine's load); 0 = off (default)\n"
            "  --exc Q0:Q1:AMP:ADV[:V]  excitation used without a table: range, amplitude, advance\n"
            "                 (actuator units) and speed (units/s); default 0:10:1:0.25:10; without V, --pace\n"
            "  --pace BLO:BHI:FRAME_US  pace the excitation to the camera: speed BLO / (4 frame periods),\n"
            "                 BLO..BHI the expected play (units), FRAME_US the camera period (also the onset\n"
            "                 detector's); overrides V\n"
            "  --instrument ID  the instrument this board drives (uint32); a table for another is\n"
            "                 refused; default PSB_INSTRUMENT_ID (psb_config.h)\n"
            "  --unit mm|deg  the actuator's unit; a table in the other is refused; default mm\n"
            "  --q-limit Q    the board commands q within +-Q units (its own travel limit), default 100\n"
            "  --c-limit C    the instrument bends within +-C deg (its own angle limit), default 180\n"
            "  --b-max B      largest play the instrument can have, units, default 10\n"
            "  --recover      stands for the STM32 board's recovery pin held at boot: both table slots\n"
            "                 are erased before the board starts (the way out of an exhausted\n"
            "                 generation counter; docs/robustness.md)\n");
}

/* Serve one connection until EOF: frames in, answers and unsolicited frames out, ticks
 * run from the monotonic clock. The motor is ideal: q measured = last set-point. */
static void serve(int in_fd, vb_clock_t *clk)
{
    uint8_t buf[4096];
    while (!stop) {
        struct pollfd p = {.fd = in_fd, .events = POLLIN};
        int r = poll(&p, 1, 1);
        if (r < 0 && errno != EINTR)
            break;
        if (r > 0) {
            ssize_t n = read(in_fd, buf, sizeof buf);
            if (n == 0 || (n < 0 && errno != EINTR && errno != EAGAIN))
                break;
            if (n > 0)
                psl_rx(&board, buf, (size_t)n);
        }
        vb_run_due(clk);
    }
}

/* --listen: up to VB_MAX_HOSTS connections at once. Each port's parser and replay window
 * are swapped into the board around its bytes; answers go back on that port, unsolicited
 * frames (stream, onset events) to the port that spoke last. */
static void serve_ports(int listen_fd, vb_clock_t *clk)
{
    static vb_port_t port[VB_MAX_HOSTS];
    uint8_t buf[4096];
    int one = 1;
    for (int k = 0; k < VB_MAX_HOSTS; k++)
        port[k].fd = -1;
    out_fd = -1;
    while (!stop) {
        struct pollfd p[1 + VB_MAX_HOSTS];
        p[0] = (struct pollfd){.fd = listen_fd, .events = POLLIN};
        for (int k = 0; k < VB_MAX_HOSTS; k++)
            p[1 + k] = (struct pollfd){.fd = port[k].fd, .events = POLLIN};
        int r = poll(p, 1 + VB_MAX_HOSTS, 1);
        if (r < 0 && errno != EINTR)
            break;
        if (r > 0 && (p[0].revents & POLLIN)) {
            int c = accept(listen_fd, NULL, NULL);
            int k = 0;
            while (k < VB_MAX_HOSTS && port[k].fd >= 0)
                k++;
            if (c >= 0 && k == VB_MAX_HOSTS) {
                close(c); /* all ports taken */
            } else if (c >= 0) {
                setsockopt(c, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
                port[k].fd = c;
                port[k].last_seq = 0;
                psf_parser_reset(&port[k].parser);
            }
        }
        for (int k = 0; r > 0 && k < VB_MAX_HOSTS; k++) {
            if (port[k].fd < 0 || !(p[1 + k].revents & (POLLIN | POLLHUP | POLLERR)))
                continue;
            ssize_t n = read(port[k].fd, buf, sizeof buf);
            if (n == 0 || (n < 0 && errno != EINTR && errno != EAGAIN)) {
                if (out_fd == port[k].fd)
                    out_fd = -1;
                close(port[k].fd);
                port[k].fd = -1;
                continue;
            }
            if (n < 0)
                continue;
            board.parser = port[k].parser;
            board.last_seq = port[k].last_seq;
            out_fd = port[k].fd;
            psl_rx(&board, buf, (size_t)n);
            port[k].parser = board.parser;
            port[k].last_seq = board.last_seq;
        }
        vb_run_due(clk);
    }
    for (int k = 0; k < VB_MAX_HOSTS; k++)
        if (port[k].fd >= 0)
            close(port[k].fd);
}

int main(int argc, char **argv)
{
    const char *flash_path = NULL;
    int listen_port = -1, use_pty = 0;
    uint32_t tick_hz = 1000;
    double time_scale = 1.0;
    unsigned long lockstep_ms = 0;
    unsigned long upload_timeout_ms = PSL_UPLOAD_TIMEOUT_US / 1000u;
    double exc[5] = {0}, pace[3];
    int have_exc = 0, have_pace = 0, recover = 0;
    pst_limits_t limits = psb_limits();
    double lim_v;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--flash") && i + 1 < argc)
            flash_path = argv[++i];
        else if (!strcmp(argv[i], "--listen") && i + 1 < argc)
            listen_port = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--pty"))
            use_pty = 1;
        else if (!strcmp(argv[i], "--stdio"))
            ;
        else if (!strcmp(argv[i], "--recover"))
            recover = 1;
        else if (!strcmp(argv[i], "--instrument") && i + 1 < argc)
            limits.instrument_id = (uint32_t)strtoul(argv[++i], NULL, 0);
        else if (!strcmp(argv[i], "--unit") && i + 1 < argc && (!strcmp(argv[i + 1], "mm") || !strcmp(argv[i + 1], "deg")))
            limits.q_unit = !strcmp(argv[++i], "mm") ? PST_Q_UNIT_MM : PST_Q_UNIT_DEG;
        else if (!strcmp(argv[i], "--q-limit") && i + 1 < argc && (lim_v = strtod(argv[++i], NULL)) > 0 && lim_v < 32768)
            limits.q_max_q16 = -(limits.q_min_q16 = -(int32_t)(lim_v * 65536.0));
        else if (!strcmp(argv[i], "--c-limit") && i + 1 < argc && (lim_v = strtod(argv[++i], NULL)) > 0 && lim_v <= 360)
            limits.c_max_q16 = -(limits.c_min_q16 = -(int32_t)(lim_v * 65536.0));
        else if (!strcmp(argv[i], "--b-max") && i + 1 < argc && (lim_v = strtod(argv[++i], NULL)) > 0 && lim_v < 32768)
            limits.b_max_q16 = (int32_t)(lim_v * 65536.0);
        else if (!strcmp(argv[i], "--upload-timeout-ms") && i + 1 < argc)
            upload_timeout_ms = strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--tick-hz") && i + 1 < argc)
            tick_hz = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--time-scale") && i + 1 < argc)
            time_scale = strtod(argv[++i], NULL);
        else if (!strcmp(argv[i], "--lockstep-ms") && i + 1 < argc)
            lockstep_ms = strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--exc") && i + 1 < argc &&
                 (have_exc = sscanf(argv[++i], "%lf:%lf:%lf:%lf:%lf", &exc[0], &exc[1], &exc[2], &exc[3], &exc[4])) >= 4)
            ;
        else if (!strcmp(argv[i], "--pace") && i + 1 < argc &&
                 sscanf(argv[++i], "%lf:%lf:%lf", &pace[0], &pace[1], &pace[2]) == 3)
            have_pace = 1;
        else {
            usage();
            return 2;
        }
    }
    if ((have_exc == 4 && !have_pace) || (have_pace && have_exc < 4)) {
        fprintf(stderr, "ps_vboard: --exc without a speed needs --pace, and --pace needs --exc\n");
        usage();
        return 2;
    }
    if (tick_hz == 0 || tick_hz > 100000 || !(time_scale > 0.0 && time_scale <= 100.0) ||
        upload_timeout_ms == 0 || upload_timeout_ms > 3600000ul || lockstep_ms > 10000ul) {
        usage();
        return 2;
    }
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    signal(SIGPIPE, SIG_IGN);

    static pss_file_t ff;
    static pss_sim_t sim;
    static uint8_t ram_flash[2 * VB_SLOT_SIZE];
    const pss_flash_t *flash;
    if (flash_path) {
        int rc = pss_file_open(&ff, flash_path, VB_SLOT_SIZE);
        if (rc == PSS_FILE_ERR_LOCKED) {
            fprintf(stderr, "%s: flash file in use by another board process; one board per flash file\n",
                    flash_path);
            return 1;
        }
        if (rc == PSS_FILE_ERR_NOT_IMAGE) {
            fprintf(stderr, "%s: not a board flash image (a regular file of %u bytes); left untouched\n",
                    flash_path, 2u * VB_SLOT_SIZE);
            return 1;
        }
        if (rc != PSS_FILE_OK) {
            perror(flash_path);
            return 1;
        }
        flash = &ff.port;
    } else {
        pss_sim_init(&sim, ram_flash, VB_SLOT_SIZE, 1);
        flash = &sim.port;
    }
    psl_config_t cfg = psl_default_config(tick_hz);
    cfg.board_id[0] = 0x56495254; /* "VIRT" */
    cfg.board_id[2] = (uint32_t)getpid();
    cfg.upload_timeout_us = (uint32_t)(upload_timeout_ms * 1000u);
    cfg.limits = limits;
    cfg.recover = recover != 0;
    if (have_exc >= 4) {
        cfg.exc.q_start_q16 = (int32_t)(exc[0] * 65536.0);
        cfg.exc.q_end_q16 = (int32_t)(exc[1] * 65536.0);
        cfg.exc.amplitude_q16 = (int32_t)(exc[2] * 65536.0);
        cfg.exc.advance_q16 = (int32_t)(exc[3] * 65536.0);
        cfg.exc.v_q32 = (int64_t)(exc[4] / tick_hz * 4294967296.0); /* units per tick, Q32.32 */
        if (have_pace) {
            /* The board's own rule (exc_pace_config), integer-only, from the camera's period. */
            double us = pace[2];
            if (!(us >= 1.0 && us <= 4294967295.0) ||
                exc_pace_config(&cfg.exc, (int32_t)(pace[0] * 65536.0 + 0.5), (int32_t)(pace[1] * 65536.0 + 0.5),
                                (uint32_t)(us + 0.5), tick_hz) != EXC_OK) {
                fprintf(stderr, "ps_vboard: --pace %g:%g:%g refused (need 0 < BLO <= BHI < AMP - ADV, "
                        "FRAME_US 1000..1000000, a speed that fits the excitation)\n", pace[0], pace[1], pace[2]);
                return 2;
            }
            cfg.onset.frame_period_us = (uint32_t)(us + 0.5);
            fprintf(stderr, "ps_vboard: excitation paced to %.9g units/s (v_q32 %lld per tick)\n",
                    (double)cfg.exc.v_q32 / 4294967296.0 * tick_hz, (long long)cfg.exc.v_q32);
        }
        exc_t probe;
        if (exc_init(&probe, &cfg.exc) != EXC_OK) {
            fprintf(stderr, "ps_vboard: --exc %g:%g:%g:%g:%g refused (need Q1 > Q0, AMP > ADV > 0, V > 0)\n",
                    exc[0], exc[1], exc[2], exc[3], exc[4]);
            return 2;
        }
    }
    psl_init(&board, &cfg, flash, write_all, NULL);
    vb_clock_t clk;
    vb_clock_init(&clk, tick_hz, time_scale, (uint32_t)(lockstep_ms * 1000u));

    if (listen_port >= 0) {
        int s = socket(AF_INET, SOCK_STREAM, 0), one = 1;
        setsockopt(s, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)listen_port),
                                .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
        socklen_t al = sizeof a;
        if (bind(s, (struct sockaddr *)&a, sizeof a) != 0 || listen(s, VB_MAX_HOSTS) != 0) {
            perror("listen");
            return 1;
        }
        getsockname(s, (struct sockaddr *)&a, &al);
        printf("listening %u\n", ntohs(a.sin_port));
        fflush(stdout);
        serve_ports(s, &clk);
    } else if (use_pty) {
        int m = posix_openpt(O_RDWR | O_NOCTTY);
        if (m < 0 || grantpt(m) != 0 || unlockpt(m) != 0) {
            perror("pty");
            return 1;
        }
        struct termios t;
        int sl = open(ptsname(m), O_RDWR | O_NOCTTY);
        tcgetattr(sl, &t);
        cfmakeraw(&t);
        tcsetattr(sl, TCSANOW, &t);
        close(sl);
        printf("pty %s\n", ptsname(m));
        fflush(stdout);
        out_fd = m;
        serve(m, &clk);
    } else {
        out_fd = 1;
        serve(0, &clk);
    }
    if (flash_path)
        pss_file_close(&ff);
    return 0;
}
