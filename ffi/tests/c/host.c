/* The host C program of ffi/tests/c_host.rs: a controller stepped from C, one measurement in
 * and one command out per cycle, as firmware would.
 *
 *   host f64|f32 PLATFORM RUN PERIOD
 *
 * PLATFORM and RUN are the numbers of CompanionPlatform and CompanionRun. Reads measurements
 * (a CompanionMeasurementF64 or ...F32, raw) from stdin until end of file; after each one
 * writes the status (int32_t) and the command (CompanionCommandF64 or ...F32, raw) to stdout.
 * At the end prints "steps N digest HEX" to stderr: FNV-1a over the bits of every command
 * (each component widened to double), to compare with other runs of the same scenario. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "companion.h"

static uint64_t digest = 0xcbf29ce484222325u;

static void mix(double x) {
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    for (int i = 0; i < 8; i++) {
        digest ^= (bits >> (8 * i)) & 0xffu;
        digest *= 0x100000001b3u;
    }
}

static CompanionController ctrl; /* the caller owns the storage: here, a static */

int main(int argc, char **argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: host f64|f32 PLATFORM RUN PERIOD\n");
        return 2;
    }
    int single = strcmp(argv[1], "f32") == 0;
    uint32_t platform = (uint32_t)strtoul(argv[2], NULL, 10);
    uint32_t run = (uint32_t)strtoul(argv[3], NULL, 10);
    double period = strtod(argv[4], NULL);

    CompanionParamError error;
    CompanionStatus status = single ? companion_f32_init_paper(&ctrl, platform, run, &error)
                                    : companion_f64_init_paper(&ctrl, platform, run, &error);
    if (status != COMPANION_STATUS_OK) {
        fprintf(stderr, "init: %s (parameter '%s', joint %d)\n", companion_status_name(status), error.param,
                (int)error.joint);
        return 1;
    }
    unsigned long steps = 0;
    for (;;) {
        int32_t s;
        if (single) {
            CompanionMeasurementF32 m;
            CompanionCommandF32 c;
            if (fread(&m, sizeof m, 1, stdin) != 1) break;
            s = companion_f32_step(&ctrl, (float)period, 0.0f, &m, &c);
            if (fwrite(&s, sizeof s, 1, stdout) != 1 || fwrite(&c, sizeof c, 1, stdout) != 1) return 1;
            mix(c.v), mix(c.v_lat), mix(c.omega), mix(c.v_xi);
            for (int j = 0; j < COMPANION_JOINTS; j++) mix(c.joints[j]);
        } else {
            CompanionMeasurementF64 m;
            CompanionCommandF64 c;
            if (fread(&m, sizeof m, 1, stdin) != 1) break;
            s = companion_f64_step(&ctrl, period, 0.0, &m, &c);
            if (fwrite(&s, sizeof s, 1, stdout) != 1 || fwrite(&c, sizeof c, 1, stdout) != 1) return 1;
            mix(c.v), mix(c.v_lat), mix(c.omega), mix(c.v_xi);
            for (int j = 0; j < COMPANION_JOINTS; j++) mix(c.joints[j]);
        }
        fflush(stdout);
        steps++;
    }
    fprintf(stderr, "steps %lu digest %016" PRIx64 "\n", steps, digest);
    return 0;
}
