/* Test driver for csrc/fixed/imf_fixed_scale.h: its AVR code
 * (IMF_SCALE_SHORT) on the host, against imf_fixed.h's helpers whose values
 * it must return.  Reads "op a b n" lines, prints "short general" per line.
 * unit_xy_k prints its result instead.  Built by tests/test_fixed_scale.py,
 * also with UBSan. */
#define IMF_SCALE_SHORT 1
#include <stdio.h>
#include <string.h>
#include "imf_fixed_scale.h"

int main(void)
{
    char op[32];
    long long a, b, n;
    while (scanf("%31s %lld %lld %lld", op, &a, &b, &n) == 4) {
        long long r = 0, g = 0;
        imf_qscale_t c;
        c.m = (int16_t)b;
        c.s = (int16_t)n;
        if (!strcmp(op, "rshrk")) {
            r = imf_rshrk((int32_t)a, (int)n);
            g = imf_rshr32((int32_t)a, (int)n);
        } else if (!strcmp(op, "shl_satk")) {
            r = imf_shl_satk((int32_t)a, (int)n);
            g = imf_shl_sat32((int32_t)a, (int)n);
        } else if (!strcmp(op, "mul32x16k")) {
            r = imf_mul32x16k((int32_t)a, (int16_t)b, (int)n);
            g = imf_mul_32x16((int32_t)a, (int16_t)b, (int)n);
        } else if (!strcmp(op, "mulk16")) { /* N = 0: shift c.s */
            r = imf_mulk16((int16_t)a, c, 0);
            g = imf_scale16((int16_t)a, c, 0);
        } else if (!strcmp(op, "mulk32")) { /* K = N: shift c.s */
            r = imf_mulk32((int32_t)a, c, 0, 0);
            g = imf_scale32((int32_t)a, c, 0, 0);
        } else if (!strcmp(op, "gain16_mul")) { /* x, c.m, c.s (c < 1): both columns the result */
            r = imf_gain16_mul((int32_t)a, imf_gain16(c, 0, 0));
            g = r;
        } else if (!strcmp(op, "cross16")) { /* a1 b1 a2 b2 packed: a b n = a1 a2 (b1 << 16 | b2) */
            const int16_t b1 = (int16_t)(n >> 16), b2 = (int16_t)(n & 0xFFFF);
            r = imf_cross16((int32_t)a, b1, (int32_t)b, b2);
            g = r;
        } else if (!strcmp(op, "shl_exact32")) {
            r = imf_shl_exact32((int32_t)a, (int)n);
            g = imf_shl_sat32((int32_t)a, (int)n);
        } else if (!strcmp(op, "unit_xy_k")) { /* prints ok a0 a1 */
            const int16_t v[3] = {(int16_t)a, (int16_t)b, (int16_t)n};
            int16_t u[2] = {0, 0};
            const int ok = imf_unit_xy_k(v, u);
            printf("%d %d %d\n", ok, u[0], u[1]);
            continue;
        } else if (!strcmp(op, "i16_to_q15")) {
            r = imf_i16_to_q15((int16_t)a);
            g = imf_q15_to_q30((int16_t)a);
        } else {
            fprintf(stderr, "unknown op %s\n", op);
            return 2;
        }
        printf("%lld %lld\n", r, g);
    }
    return 0;
}
