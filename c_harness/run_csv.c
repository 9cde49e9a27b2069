/*
 * run_csv - run a generated observer target over a CSV trajectory (no Python needed).
 *
 * Usage: run_csv in.csv out.csv [est0]
 *
 *   in.csv   one header line (names are ignored; it must have 1 + NY + NU columns),
 *            then one row per sample: t, y_1..y_NY, u_1..u_NU
 *   out.csv  written as: header "t,est0,...,est<NEST-1>", then t, est_1..est_NEST per row,
 *            each number printed with %.17g (round-trips exactly)
 *   est0     optional initial estimate, NEST comma-separated numbers (default: zeros)
 *
 * The target is initialised with y0 = the first row's y and est0, then stepped once per row;
 * est at a row is the estimate at that sample.  The time column is always used as the time
 * stamps of the samples (a jittered log runs as logged; the t column is copied to the output):
 * each row is one <prefix>_step_dt(&s, h, y, u, est) with h the interval, computed in double,
 *   first-order hold (HOLD_FOH = 1): since the previous row, h = t_k - t_k-1 (the first row
 *     integrates nothing: <prefix>_step);
 *   zero-order hold: to the next row, h = t_k+1 - t_k (the last row: <prefix>_step, DT);
 * and an interval equal to DT up to the rounding of its stamps (|h - DT| <= STAMP_ULPS
 * DBL_EPSILON max(|t_k-1|, |t_k|), as the target's run_t) is exactly DT: <prefix>_step, so a
 * uniform log gives <prefix>_run's results bit for bit.  Stamps that do not increase, or an
 * interval beyond the target's SPLIT_MAX * DT_MAX, make step_dt return ERR_BAD_ARG (exit 3);
 * an interval above DT_MAX (a dropped sample) is split by the target (see its header).
 *
 * Exit status: 0 success; 1 bad input file or I/O error; 2 usage error; 3 the target
 * returned a non-zero status (row, status name and h on stderr).  On failure out.csv is not
 * written (the output goes to a temporary file renamed on success).
 *
 * Build (see Makefile): cc -O3 -std=c99 -DOBS=<prefix> -DOBS_UPPER=<PREFIX>
 *   -DOBS_HEADER='"<prefix>.h"' -I <target dir> run_csv.c <prefix>.c <prefix>_kernels.c -lm
 */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obs_bind.h"

#define EXIT_INPUT 1
#define EXIT_USAGE 2
#define EXIT_STATUS 3

#define N_COLS (1 + OBS_NY + OBS_NU)
#define OBS_HOLD_FOH OBS_SIZE(HOLD_FOH)

static const char *prog = "run_csv";

/* t_b - t_a, or DT when it is DT up to the rounding of the stamps (the target's run_t rule,
   in double; stamps that are not finite give what they give: NaN or Inf, refused by step_dt) */
static double interval(double a, double b)
{
    double h = b - a, m = fabs(a) > fabs(b) ? fabs(a) : fabs(b);
    return isfinite(h) && fabs(h - (double)OBS_DT) <= OBS_SIZE(STAMP_ULPS) * DBL_EPSILON * m ? (double)OBS_DT : h;
}

/* One sample of the target: <prefix>_step when `first` (first-order hold, first row) or h is DT,
   else <prefix>_step_dt with h; writes the row of out.csv. Returns 0, or the exit status after
   printing why. */
static int sample(OBS_STATE *state, const double *vals, int first, double h, FILE *out, const char *in_path,
                  long line_no, long row, const char *tmp_path)
{
    OBS_REAL yu[N_COLS - 1]; /* y, u of a row in the target's real type */
    OBS_REAL est[OBS_LEN(OBS_NEST)];
    int i, st, fixed = first || h == (double)OBS_DT;
    for (i = 0; i < N_COLS - 1; ++i) yu[i] = (OBS_REAL)vals[i + 1];
    st = fixed ? OBS_FN(step)(state, yu, yu + OBS_NY, est)
               : OBS_FN(step_dt)(state, (OBS_REAL)h, yu, yu + OBS_NY, est);
    if (st != 0) {
        fprintf(stderr, "%s: %s:%ld: data row %ld (t=%.17g): %s_%s returned %d: %s", prog, in_path,
                line_no, row, vals[0], OBS_NAME, fixed ? "step" : "step_dt", st, obs_status_name(st));
        if (fixed) fprintf(stderr, "\n");
        else fprintf(stderr, " (dt = %.17g, from the t column)\n", h);
        return EXIT_STATUS;
    }
    fprintf(out, "%.17g", vals[0]);
    for (i = 0; i < (int)OBS_NEST; ++i) fprintf(out, ",%.17g", (double)est[i]);
    if (fprintf(out, "\n") < 0) {
        fprintf(stderr, "%s: write error on '%s': %s\n", prog, tmp_path, strerror(errno));
        return EXIT_INPUT;
    }
    return 0;
}

/* Read one line (without the trailing newline / CR) into a growing buffer.
 * Returns 1 if a line was read, 0 at end of file, -1 on a read or memory error. */
static int read_line(FILE *f, char **buf, size_t *cap, size_t *len)
{
    int c;
    size_t n = 0;
    int got = 0;
    while ((c = getc(f)) != EOF) {
        got = 1;
        if (c == '\n') break;
        if (n + 1 >= *cap) {
            size_t new_cap = *cap ? 2 * *cap : 256;
            char *nb = (char *)realloc(*buf, new_cap);
            if (!nb) return -1;
            *buf = nb;
            *cap = new_cap;
        }
        (*buf)[n++] = (char)c;
    }
    if (ferror(f)) return -1;
    if (!got) return 0;
    if (!*buf) { /* empty line and no buffer yet */
        *buf = (char *)malloc(256);
        if (!*buf) return -1;
        *cap = 256;
    }
    if (n > 0 && (*buf)[n - 1] == '\r') --n;
    (*buf)[n] = '\0';
    *len = n;
    return 1;
}

static int is_blank(const char *s)
{
    for (; *s; ++s)
        if (*s != ' ' && *s != '\t') return 0;
    return 1;
}

static size_t count_fields(const char *s)
{
    size_t n = 1;
    for (; *s; ++s)
        if (*s == ',') ++n;
    return n;
}

/* Parse exactly `n` comma-separated numbers from `s` into `out`.
 * On failure returns 0 and sets *bad_col (1-based) and copies the bad field into `bad`. */
static int parse_numbers(const char *s, double *out, size_t n, size_t *bad_col, char *bad,
                         size_t bad_size)
{
    size_t i;
    const char *p = s;
    for (i = 0; i < n; ++i) {
        const char *field = p;
        const char *field_end = strchr(p, ',');
        char *end = NULL;
        double v;
        if (!field_end) field_end = p + strlen(p);
        while (field < field_end && (*field == ' ' || *field == '\t')) ++field;
        v = strtod(field, &end);
        if (end == field || end > field_end) goto fail;
        while (end < field_end && (*end == ' ' || *end == '\t')) ++end;
        if (end != field_end) goto fail;
        out[i] = v;
        p = *field_end ? field_end + 1 : field_end;
        continue;
    fail:
        *bad_col = i + 1;
        {
            size_t len = (size_t)(field_end - p);
            if (len >= bad_size) len = bad_size - 1;
            memcpy(bad, p, len);
            bad[len] = '\0';
        }
        return 0;
    }
    return 1;
}

static void usage(void)
{
    fprintf(stderr,
            "usage: %s in.csv out.csv [est0]\n"
            "  target '%s': in.csv columns t, y_1..y_%d, u_1..u_%d (%d columns, one header line);\n"
            "  est0: %d comma-separated numbers (default zeros)\n",
            prog, OBS_NAME, (int)OBS_NY, (int)OBS_NU, (int)N_COLS, (int)OBS_NEST);
}

int main(int argc, char **argv)
{
    const char *in_path, *out_path;
    char *tmp_path = NULL;
    FILE *in = NULL, *out = NULL;
    char *line = NULL;
    size_t cap = 0, len = 0;
    long line_no = 0, row = 0, pending_line = 0;
    int rc = EXIT_INPUT, r;
    double est0_in[OBS_LEN(OBS_NEST)];
    OBS_REAL est0[OBS_LEN(OBS_NEST)];
    int have_est0 = 0;
    double vals[N_COLS], pending[N_COLS]; /* zero-order hold: the row waiting for the next stamp */
    OBS_REAL yu[N_COLS - 1]; /* y, u of a row in the target's real type */
    double t_prev = 0.0;
    OBS_STATE state;
    char bad[64];
    size_t bad_col = 0;

    if (argc < 3 || argc > 4) {
        usage();
        return EXIT_USAGE;
    }
    in_path = argv[1];
    out_path = argv[2];
    if (argc == 4) {
        size_t n = count_fields(argv[3]);
        if (n != (size_t)OBS_NEST) {
            fprintf(stderr, "%s: est0 must have %d comma-separated numbers (NEST of '%s'), got %lu\n",
                    prog, (int)OBS_NEST, OBS_NAME, (unsigned long)n);
            return EXIT_USAGE;
        }
        if (!parse_numbers(argv[3], est0_in, (size_t)OBS_NEST, &bad_col, bad, sizeof bad)) {
            fprintf(stderr, "%s: est0 entry %lu ('%s') is not a number\n", prog,
                    (unsigned long)bad_col, bad);
            return EXIT_USAGE;
        }
        {
            int k;
            for (k = 0; k < (int)OBS_NEST; ++k) est0[k] = (OBS_REAL)est0_in[k];
        }
        have_est0 = 1;
    }

    in = fopen(in_path, "r");
    if (!in) {
        fprintf(stderr, "%s: cannot open input '%s': %s\n", prog, in_path, strerror(errno));
        return EXIT_INPUT;
    }

    /* header */
    r = read_line(in, &line, &cap, &len);
    ++line_no;
    if (r < 0) {
        fprintf(stderr, "%s: %s: read error or out of memory\n", prog, in_path);
        goto done;
    }
    if (r == 0 || is_blank(line)) {
        fprintf(stderr, "%s: %s: empty file (expected a header line with %d columns: t, %d y, %d u)\n",
                prog, in_path, (int)N_COLS, (int)OBS_NY, (int)OBS_NU);
        goto done;
    }
    if (count_fields(line) != (size_t)N_COLS) {
        fprintf(stderr,
                "%s: %s:1: header has %lu columns, target '%s' expects %d (t, %d y, %d u)\n",
                prog, in_path, (unsigned long)count_fields(line), OBS_NAME, (int)N_COLS,
                (int)OBS_NY, (int)OBS_NU);
        goto done;
    }

    tmp_path = (char *)malloc(strlen(out_path) + 5);
    if (!tmp_path) {
        fprintf(stderr, "%s: out of memory\n", prog);
        goto done;
    }
    strcpy(tmp_path, out_path);
    strcat(tmp_path, ".tmp");
    out = fopen(tmp_path, "w");
    if (!out) {
        fprintf(stderr, "%s: cannot open output '%s': %s\n", prog, tmp_path, strerror(errno));
        goto done;
    }
    fprintf(out, "t");
    {
        int i;
        for (i = 0; i < (int)OBS_NEST; ++i) fprintf(out, ",est%d", i);
    }
    fprintf(out, "\n");

    for (;;) {
        int st, i;
        size_t nf;
        double h;
        r = read_line(in, &line, &cap, &len);
        ++line_no;
        if (r < 0) {
            fprintf(stderr, "%s: %s:%ld: read error or out of memory\n", prog, in_path, line_no);
            goto done;
        }
        if (r == 0) break;
        if (is_blank(line)) continue;
        nf = count_fields(line);
        if (nf != (size_t)N_COLS) {
            fprintf(stderr, "%s: %s:%ld: row has %lu columns, expected %d (t, %d y, %d u)\n", prog,
                    in_path, line_no, (unsigned long)nf, (int)N_COLS, (int)OBS_NY, (int)OBS_NU);
            goto done;
        }
        if (!parse_numbers(line, vals, (size_t)N_COLS, &bad_col, bad, sizeof bad)) {
            fprintf(stderr, "%s: %s:%ld: column %lu ('%s') %s\n", prog, in_path, line_no,
                    (unsigned long)bad_col, bad, is_blank(bad) ? "is empty" : "is not a number");
            goto done;
        }
        ++row;
        if (row == 1) {
            for (i = 0; i < N_COLS - 1; ++i) yu[i] = (OBS_REAL)vals[i + 1];
            st = OBS_FN(init)(&state, NULL, yu, have_est0 ? est0 : NULL);
            if (st != 0) {
                fprintf(stderr, "%s: %s:%ld: data row 1 (t=%.17g): %s_init returned %d: %s\n", prog,
                        in_path, line_no, vals[0], OBS_NAME, st, obs_status_name(st));
                rc = EXIT_STATUS;
                goto done;
            }
        }
        if (OBS_HOLD_FOH) {          /* the interval before this row */
            h = row == 1 ? (double)OBS_DT : interval(t_prev, vals[0]);
            if ((st = sample(&state, vals, row == 1, h, out, in_path, line_no, row, tmp_path)) != 0) {
                rc = st;
                goto done;
            }
        } else if (row > 1) {        /* the pending row, over the interval to this one */
            h = interval(pending[0], vals[0]);
            if ((st = sample(&state, pending, 0, h, out, in_path, pending_line, row - 1, tmp_path)) != 0) {
                rc = st;
                goto done;
            }
        }
        if (!OBS_HOLD_FOH) {
            memcpy(pending, vals, sizeof pending);
            pending_line = line_no;
        }
        t_prev = vals[0];
    }
    if (row == 0) {
        fprintf(stderr, "%s: %s: no data rows after the header\n", prog, in_path);
        goto done;
    }
    if (!OBS_HOLD_FOH) {             /* the last row: the next stamp is unknown, DT */
        int st = sample(&state, pending, 0, (double)OBS_DT, out, in_path, pending_line, row, tmp_path);
        if (st != 0) {
            rc = st;
            goto done;
        }
    }
    if (fclose(out) != 0) {
        out = NULL;
        fprintf(stderr, "%s: write error on '%s': %s\n", prog, tmp_path, strerror(errno));
        goto done;
    }
    out = NULL;
    if (rename(tmp_path, out_path) != 0) {
        fprintf(stderr, "%s: cannot rename '%s' to '%s': %s\n", prog, tmp_path, out_path,
                strerror(errno));
        goto done;
    }
    rc = 0;

done:
    if (out) fclose(out);
    if (rc != 0 && tmp_path) remove(tmp_path);
    if (in) fclose(in);
    free(line);
    free(tmp_path);
    return rc;
}
