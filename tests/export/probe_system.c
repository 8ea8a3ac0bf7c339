/* Prints the exported system's functions at one state: the C side of the weighted-system check in
   tests/export/test_export.cpp. It includes the exported source, so that the static system functions the step calls
   (hinf_filter_drift, _disturbance_gain, _measurement, _measurement_jacobian) are the ones printed.
   Usage: probe_system T X_1 ... X_n   Prints rows "A,...", "B,..." (row-major [n x nv]), "C,...", "H,..." ([m x n]). */
#include <stdio.h>
#include <stdlib.h>

#include "hinf_filter.c"

static void row(const char* name, const double* v, int count) {
    int i;
    printf("%s", name);
    for (i = 0; i < count; ++i) printf(",%.17g", v[i]);
    printf("\n");
}

int main(int argc, char** argv) {
    double x[hinf_filter_N], A[hinf_filter_N], B[hinf_filter_N * hinf_filter_NV], C[hinf_filter_M],
        H[hinf_filter_M * hinf_filter_N], t;
    int i;
    if (argc != 2 + hinf_filter_N) {
        fprintf(stderr, "usage: probe_system T X_1 ... X_%d\n", hinf_filter_N);
        return 2;
    }
    t = atof(argv[1]);
    for (i = 0; i < hinf_filter_N; ++i) x[i] = atof(argv[2 + i]);
    hinf_filter_drift(A, x, t);
    hinf_filter_disturbance_gain(B, x, t);
    hinf_filter_measurement(C, x, t);
    hinf_filter_measurement_jacobian(H, x, t);
    row("A", A, hinf_filter_N);
    row("B", B, hinf_filter_N * hinf_filter_NV);
    row("C", C, hinf_filter_M);
    row("H", H, hinf_filter_M * hinf_filter_N);
    return 0;
}
