/* Test driver for csrc/fixed/imf_fixed.h: reads "op a b n" lines on stdin,
 * prints one result line each.  Built by tests/test_fixed_core.py, also
 * with -fsanitize=undefined -fno-sanitize-recover. */
#include <stdio.h>
#include <string.h>
#include "imf_fixed_init.h"
#include "imf_fixed_quat.h"

int main(void)
{
    char op[32];
    long long a, b, n;
    while (scanf("%31s %lld %lld %lld", op, &a, &b, &n) == 4) {
        long long r = 0, r2 = 0;
        int sh = 0;
        if (!strcmp(op, "rshr32")) r = imf_rshr32((int32_t)a, (int)n);
        else if (!strcmp(op, "asr32")) r = imf_asr32((int32_t)a, (int)n);
        else if (!strcmp(op, "shl_sat32")) r = imf_shl_sat32((int32_t)a, (int)n);
        else if (!strcmp(op, "rshift_sat32")) r = imf_rshift_sat32((int32_t)a, (int)n);
        else if (!strcmp(op, "sat_q15")) r = imf_sat_q15((int32_t)a);
        else if (!strcmp(op, "sat_q15s")) r = imf_sat_q15s((int32_t)a);
        else if (!strcmp(op, "add_sat32")) r = imf_add_sat32((int32_t)a, (int32_t)b);
        else if (!strcmp(op, "sub_sat32")) r = imf_sub_sat32((int32_t)a, (int32_t)b);
        else if (!strcmp(op, "add_sat_q15")) r = imf_add_sat_q15((int16_t)a, (int16_t)b);
        else if (!strcmp(op, "sub_sat_q15")) r = imf_sub_sat_q15((int16_t)a, (int16_t)b);
        else if (!strcmp(op, "mul_q15")) r = imf_mul_q15((int16_t)a, (int16_t)b);
        else if (!strcmp(op, "mul_q15_q30")) r = imf_mul_q15_q30((int16_t)a, (int16_t)b);
        else if (!strcmp(op, "mul_32x16")) r = imf_mul_32x16((int32_t)a, (int16_t)b, (int)n);
        else if (!strcmp(op, "mul_32x16_s")) r = imf_mul_32x16_s((int32_t)a, (int16_t)b, (int)n);
        else if (!strcmp(op, "q_mul_hq_p32")) r = imf_q_mul_hq_p32((int32_t)a, (int16_t)b);
        else if (!strcmp(op, "isqrt_u32")) r = imf_isqrt_u32((uint32_t)a);
        else if (!strcmp(op, "invsqrt_u32")) { r = imf_invsqrt_u32((uint32_t)a, &sh); r2 = sh; }
        else if (!strcmp(op, "q30_to_q15")) r = imf_q30_to_q15((int32_t)a);
        else if (!strcmp(op, "q15_to_q30")) r = imf_q15_to_q30((int16_t)a);
        else if (!strcmp(op, "qn_to_q15s")) r = imf_qn_to_q15s((int32_t)a, (int)n);
        else if (!strcmp(op, "qscale")) {
            union { double d; unsigned long long u; } v;
            imf_qscale_t c;
            v.u = (unsigned long long)a;
            c = imf_qscale_from_double(v.d);
            r = c.m; r2 = c.s;
        }
        else { fprintf(stderr, "unknown op %s\n", op); return 2; }
        printf("%lld %lld\n", r, r2);
    }
    return 0;
}
