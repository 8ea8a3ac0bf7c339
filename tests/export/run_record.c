/* Runs an exported filter (hinf export, default prefix hinf_filter) over a record and prints its estimates:
   the C side of tests/export/test_export.cpp and the timing of docs/export.md. C99 + libm only.
   Usage: run_record RECORD.csv [REPEATS]   RECORD: rows "t,y_1,...,y_m" (no header)
   Prints K rows of x^ before each step (as estimates.h5's xhat), then "final" x^, then "us_per_step T". */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "hinf_filter.h"

int main(int argc, char** argv) {
    FILE* f;
    double *t = NULL, *y = NULL, dt, seconds;
    long K = 0, cap = 0, k, r, repeats = argc > 2 ? atol(argv[2]) : 1;
    int i;
    hinf_filter_state s;
    clock_t c0;
    if (argc < 2 || !(f = fopen(argv[1], "r"))) {
        fprintf(stderr, "usage: run_record RECORD.csv [REPEATS]\n");
        return 2;
    }
    for (;;) {
        double row[1 + hinf_filter_M];
        for (i = 0; i < 1 + hinf_filter_M; ++i)
            if (fscanf(f, i ? " ,%lf" : " %lf", &row[i]) != 1) break;
        if (i < 1 + hinf_filter_M) break;
        if (K == cap) {
            cap = cap ? 2 * cap : 1024;
            t = realloc(t, sizeof(double) * cap);
            y = realloc(y, sizeof(double) * cap * hinf_filter_M);
        }
        t[K] = row[0];
        for (i = 0; i < hinf_filter_M; ++i) y[K * hinf_filter_M + i] = row[1 + i];
        ++K;
    }
    fclose(f);
    if (K < 2) return 2;
    dt = (t[K - 1] - t[0]) / (double)(K - 1); /* the record's interval, as hinf filter takes it */
    hinf_filter_init(&s, NULL);
    for (k = 0; k < K; ++k) {
        for (i = 0; i < hinf_filter_N; ++i) printf(i ? ",%.17g" : "%.17g", s.xhat[i]);
        printf("\n");
        hinf_filter_step(&s, y + k * hinf_filter_M, t[k], dt);
    }
    printf("final");
    for (i = 0; i < hinf_filter_N; ++i) printf(",%.17g", s.xhat[i]);
    printf("\n");
    c0 = clock();
    for (r = 0; r < repeats; ++r) {
        hinf_filter_init(&s, NULL);
        for (k = 0; k < K; ++k) hinf_filter_step(&s, y + k * hinf_filter_M, t[k], dt);
    }
    seconds = (double)(clock() - c0) / CLOCKS_PER_SEC;
    printf("us_per_step %.4g\n", 1e6 * seconds / (double)(repeats * K));
    free(t);
    free(y);
    return 0;
}
