/* csvparse.h: numbers from CSV text, column by column, for imufuse.io's reader
 * (imufuse_c/_csvin.pyx). Host-only speed layer: not part of the embeddable csrc/ library.
 *
 * What it reads is what numpy.loadtxt(delimiter=d, usecols=..., quotechar='"', comments="#")
 * reads from the same lines, to the bit:
 *  - lines end at "\n", "\r\n" or a lone "\r"; a line that is blank or holds only a comment
 *    ("#" to the end of the line, outside quotes) is skipped;
 *  - fields are split at the delimiter, or at runs of blanks (space, tab) when the delimiter
 *    is 0; a field may be quoted ("1.5"; "" inside quotes is one quote);
 *  - a used field is a decimal number with optional sign, fraction and exponent, or
 *    nan/inf/infinity in any case, surrounded by optional blanks; anything else (an empty
 *    field, hex, underscores, trailing text) is an error at that line and column;
 *  - values are correctly rounded: decimal significands of at most 19 digits with a
 *    power of ten both exactly representable go through one exact multiplication or
 *    division (the classic exact fast path, bit for bit with strtod), all others through
 *    strtod, which glibc rounds correctly. The caller checks that the C locale's decimal
 *    point is ".";
 *  - with a decimal comma (a delimiter other than ","), a "," inside a used field is
 *    read as ".";
 *  - a row with more fields than the header has columns (one trailing empty field allowed,
 *    rows holding a quote exempted) is an error: its values would come from the wrong
 *    columns;
 *  - a NUL byte ends the text (the NUL-filled tail of a preallocated file): the caller is
 *    told, with the partial row before it, which is dropped.
 *
 * The scans stop at a 0 byte: the caller puts one after the text (csvp_parse).
 * Everything is static: the one translation unit that includes it is _csvin.pyx.
 */
#ifndef IMUFUSE_CSVPARSE_H
#define IMUFUSE_CSVPARSE_H

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

enum {
    CSVP_OK = 0,
    CSVP_BAD_NUMBER = 1, /* a used field is not a number: err_line, err_col */
    CSVP_FEW_FIELDS = 2, /* a row without the used column: err_line, err_col */
    CSVP_MANY_FIELDS = 3, /* more fields than the header: err_line, err_col = fields */
    CSVP_FULL = 4 /* the output has no room for another row */
};

typedef struct {
    char delim; /* 0: runs of blanks */
    int decimal_comma; /* read "," inside a used field as "." */
    int width; /* the header's columns (for the extra-fields check) */
    int ncol; /* used columns */
    const int *slot; /* slot[field] = output column of that field, or -1; nslot entries */
    int nslot;
    double *out; /* row-major, ncol per row */
    long cap; /* rows out can hold */
    long rows; /* rows written */
    long line; /* lines consumed (blank and comment lines included) */
    int nul; /* a NUL byte was met: reading stops there */
    long err_line; /* 1-based line of the error, counted from the first line parsed */
    int err_col; /* field index of the error */
    unsigned char stop[256]; /* csvp_init: the bytes that end a field's scan */
} csvp_state;

/* The stop table of st->delim: the delimiter (or the blanks), line ends, "#", '"' and 0. */
static void csvp_init(csvp_state *st)
{
    memset(st->stop, 0, sizeof st->stop);
    st->stop[0] = 1; /* the sentinel after the text, and a NUL in it */
    st->stop[(unsigned char)'\n'] = st->stop[(unsigned char)'\r'] = 1;
    st->stop[(unsigned char)'#'] = st->stop[(unsigned char)'"'] = 1;
    if (st->delim) {
        st->stop[(unsigned char)st->delim] = 1;
    } else {
        st->stop[(unsigned char)' '] = st->stop[(unsigned char)'\t'] = 1;
    }
}

static const double csvp_pow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                      1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                      1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static int csvp_blank(char c) { return c == ' ' || c == '\t'; }

/* what Python's str.strip() and numpy strip around a number */
static int csvp_space(char c) { return c == ' ' || (c >= '\t' && c <= '\r'); }

static int csvp_lower_eq(const char *s, const char *e, const char *word)
{
    size_t n = strlen(word), i;
    if ((size_t)(e - s) != n) return 0;
    for (i = 0; i < n; i++) {
        char c = s[i];
        if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
        if (c != word[i]) return 0;
    }
    return 1;
}

/* One number from [s, e) (already unquoted): 0 and *v, or -1. */
static int csvp_number(const char *s, const char *e, int decimal_comma, double *v)
{
    char buf[128];
    const char *p;
    int neg = 0, ndig = 0, nfrac = 0, any = 0, expneg = 0;
    unsigned long long m = 0;
    long ex = 0;
    size_t n;
    while (s < e && csvp_space(*s)) s++;
    while (e > s && csvp_space(e[-1])) e--;
    if (s == e) return -1;
    p = s;
    if (*p == '+' || *p == '-') neg = (*p++ == '-');
    if (p < e && (*p == 'n' || *p == 'N' || *p == 'i' || *p == 'I')) {
        if (csvp_lower_eq(p, e, "nan")) {
            *v = neg ? -(double)NAN : (double)NAN;
            return 0;
        }
        if (csvp_lower_eq(p, e, "inf") || csvp_lower_eq(p, e, "infinity")) {
            *v = neg ? -(double)INFINITY : (double)INFINITY;
            return 0;
        }
        return -1;
    }
    /* the grammar: digits [ (.|,) digits ] [ (e|E) [sign] digits ], at least one digit
       before the exponent */
    while (p < e && *p >= '0' && *p <= '9') {
        any = 1;
        if (m || *p != '0') {
            if (ndig < 19) m = m * 10u + (unsigned)(*p - '0');
            else ex++;
            ndig++;
        }
        p++;
    }
    if (p < e && (*p == '.' || (decimal_comma && *p == ','))) {
        p++;
        while (p < e && *p >= '0' && *p <= '9') {
            any = 1;
            if (m || *p != '0') {
                if (ndig < 19) {
                    m = m * 10u + (unsigned)(*p - '0');
                    nfrac++;
                }
                ndig++;
            } else {
                nfrac++;
            }
            p++;
        }
    }
    if (!any) return -1;
    if (p < e && (*p == 'e' || *p == 'E')) {
        long x = 0;
        int xd = 0;
        p++;
        if (p < e && (*p == '+' || *p == '-')) expneg = (*p++ == '-');
        while (p < e && *p >= '0' && *p <= '9') {
            if (x < 100000) x = x * 10 + (*p - '0');
            xd++;
            p++;
        }
        if (!xd) return -1;
        ex += expneg ? -x : x;
    }
    if (p != e) return -1;
    ex -= nfrac;
    /* exact: m < 2^53 and 10^|ex| exact (|ex| <= 22): one correctly rounded operation */
    if (ndig <= 19 && m < (1ull << 53) && ex >= -22 && ex <= 22) {
        double d = (double)m;
        d = ex < 0 ? d / csvp_pow10[-ex] : d * csvp_pow10[ex];
        *v = neg ? -d : d;
        return 0;
    }
    /* everything else: strtod on a copy (decimal comma turned into a point) */
    n = (size_t)(e - s);
    {
        char *t = n < sizeof buf ? buf : malloc(n + 1), *end;
        int ok;
        if (!t) return -1;
        memcpy(t, s, n);
        t[n] = 0;
        if (decimal_comma) {
            size_t i;
            for (i = 0; i < n; i++)
                if (t[i] == ',') t[i] = '.';
        }
        errno = 0;
        *v = strtod(t, &end);
        ok = end == t + n;
        if (t != buf) free(t);
        return ok ? 0 : -1;
    }
}

/* The common number, read where the field starts (one scan of its bytes): optional blanks,
   sign, at most 19 significant digits, a fraction, an exponent, optional blanks, then the end
   of the field (a stop byte other than a quote, or lim). Returns the end of the field, or 0
   when the field is anything else (nan, more digits, a decimal comma, text: csvp_number then
   reads or refuses it). The value is the exact fast path's, bit for bit with csvp_number. */
static const char *csvp_number_at(const csvp_state *st, const char *p, const char *lim,
                                  double *v)
{
    int neg = 0, nint, nfrac = 0;
    unsigned long long m = 0; /* wraps beyond 19 digits, which are refused below */
    long ex = 0;
    const char *d0;
    double d;
    while (*p == ' ' || *p == '\t') p++;
    if (*p == '+' || *p == '-') neg = (*p++ == '-');
    for (d0 = p; (unsigned)(*p - '0') < 10u; p++) m = m * 10u + (unsigned)(*p - '0');
    nint = (int)(p - d0);
    if (*p == '.') {
        for (d0 = ++p; (unsigned)(*p - '0') < 10u; p++)
            m = m * 10u + (unsigned)(*p - '0');
        nfrac = (int)(p - d0);
    }
    if (nint + nfrac == 0 || nint + nfrac > 19) return 0;
    if (p < lim && (*p == 'e' || *p == 'E')) {
        long x = 0;
        int xneg = 0;
        p++;
        if (p < lim && (*p == '+' || *p == '-')) xneg = (*p++ == '-');
        for (d0 = p; p < lim && (unsigned)(*p - '0') < 10u && p - d0 < 6; p++)
            x = x * 10 + (*p - '0');
        if (p == d0) return 0;
        ex = xneg ? -x : x;
    }
    if (st->delim)
        while (p < lim && csvp_blank(*p)) p++;
    if (p < lim && (!st->stop[(unsigned char)*p] || *p == '"')) return 0;
    ex -= nfrac;
    if (m >= (1ull << 53) || ex < -22 || ex > 22) return 0;
    d = (double)m;
    d = ex < 0 ? d / csvp_pow10[-ex] : d * csvp_pow10[ex];
    *v = neg ? -d : d;
    return p;
}

/* A row with more values than the header has columns (checked before its numbers are
   blamed): delimiters counted over the line without its trailing blanks and one trailing
   delimiter; rows holding a quote are exempt. Sets err_line and err_col (the values). */
static int csvp_too_many(csvp_state *st, const char *ln, const char *le)
{
    const char *t = le, *r;
    int n = 0;
    if (!st->delim || memchr(ln, '"', (size_t)(le - ln))) return 0;
    while (t > ln && csvp_space(t[-1])) t--;
    if (t > ln && t[-1] == st->delim) t--;
    for (r = ln; r < t; r++) n += (*r == st->delim);
    if (n < st->width) return 0;
    st->err_line = st->line;
    st->err_col = n + 1;
    return 1;
}

/* The end of the line from q: its first \n or \r, or lim. */
static const char *csvp_line_end(const char *q, const char *lim)
{
    while (q < lim && *q != '\n' && *q != '\r') q++;
    return q;
}

/* Parse the complete lines of [text, text + len); final: the text ends there (the last line
   needs no line end). text[len] must be a 0 byte (a sentinel that ends every scan). Returns a CSVP_ status; *used: the bytes consumed (whole lines; at a
   NUL, st->nul is set and *used is the start of the partial row before it). One pass over
   the bytes: a row's fields are found, its numbers read and its values counted as it is
   scanned; its line end is where the scan stops. */
static int csvp_parse(csvp_state *st, const char *text, long len, int final, long *used)
{
    const char *p = text, *end = text + len;
    const char *nulp = memchr(text, 0, (size_t)len);
    const char *lim = nulp ? nulp : end;
    const char d = st->delim;
    *used = 0;
    for (;;) {
        const char *ln = p, *q = p, *le;
        int row = 0;
        while (q < lim && csvp_blank(*q)) q++;
        if (q < lim && *q != '\n' && *q != '\r' && *q != '#') {
            /* a row: its fields, to the line end */
            double *out;
            int field = 0, got = 0, quote = 0, comment = 0, last_blank = 0;
            if (st->rows >= st->cap) {
                *used = (long)(ln - text);
                return CSVP_FULL;
            }
            out = st->out + st->rows * st->ncol;
            if (d) q = ln; /* blanks before a delimited field are the field's */
            for (;;) {
                const char *fs = q, *fe = q, *r;
                int s = field < st->nslot ? st->slot[field] : -1, quoted = 0;
                if (s >= 0 && (r = csvp_number_at(st, q, lim, &out[s])) != 0) {
                    /* the common case: the number read as the field is scanned */
                    q = r;
                    got++;
                    s = -1;
                } else if (q < lim && *q == '"') {
                    /* quoted: to the closing quote ("" is a quote), then to the delimiter */
                    quote = quoted = 1;
                    fs = ++q;
                    while (q < lim && *q != '\n' && *q != '\r') {
                        if (*q != '"') q++;
                        else if (q + 1 < lim && q[1] == '"') q += 2;
                        else break;
                    }
                    fe = q;
                    if (q < lim && *q == '"') q++;
                }
                for (;;) {
                    while (!st->stop[(unsigned char)*q]) q++;
                    if (q < lim && *q == '"') {
                        quote = 1; /* a quote inside a field: part of it */
                        q++;
                        continue;
                    }
                    break;
                }
                if (q == lim && !nulp && !final) {
                    *used = (long)(ln - text); /* the line goes on in the next block */
                    return CSVP_OK;
                }
                if (q == lim && nulp) {
                    st->nul = 1; /* a row cut by the NUL: the caller reports it */
                    *used = (long)(ln - text);
                    return CSVP_OK;
                }
                if (!quoted) fe = q;
                if (s >= 0) {
                    if (csvp_number(fs, fe, st->decimal_comma, &out[s]) != 0) {
                        le = csvp_line_end(q, lim);
                        st->line++;
                        *used = (long)(ln - text);
                        if (csvp_too_many(st, ln, le)) return CSVP_MANY_FIELDS;
                        st->err_line = st->line;
                        st->err_col = field;
                        return CSVP_BAD_NUMBER;
                    }
                    got++;
                }
                field++;
                if (q < lim && *q == '#') {
                    comment = 1;
                    q = csvp_line_end(q, lim);
                    break;
                }
                if (q == lim || *q == '\n' || *q == '\r') {
                    const char *t = fs;
                    while (t < fe && csvp_space(*t)) t++;
                    last_blank = (t == fe);
                    break;
                }
                if (d) {
                    q++; /* past the delimiter: a field follows, empty or not */
                } else {
                    while (q < lim && csvp_blank(*q)) q++;
                    if (q == lim || *q == '\n' || *q == '\r' || *q == '#') {
                        if (q < lim && *q == '#') {
                            comment = 1;
                            q = csvp_line_end(q, lim);
                        }
                        break;
                    }
                }
            }
            if (q == lim && !nulp && !final) {
                *used = (long)(ln - text);
                return CSVP_OK;
            }
            if (q == lim && nulp) {
                st->nul = 1; /* the partial row before the NUL: the caller reports it */
                *used = (long)(ln - text);
                return CSVP_OK;
            }
            le = q;
            st->line++;
            if (got < st->ncol) {
                st->err_line = st->line;
                st->err_col = field;
                *used = (long)(ln - text);
                return CSVP_FEW_FIELDS;
            }
            /* more values than the header has columns (one trailing delimiter allowed) */
            if (d && !quote &&
                (comment ? csvp_too_many(st, ln, le) : field - 1 - last_blank >= st->width)) {
                if (!comment) {
                    st->err_line = st->line;
                    st->err_col = field - last_blank;
                }
                *used = (long)(ln - text);
                return CSVP_MANY_FIELDS;
            }
            row = 1;
        } else {
            /* a blank or comment line */
            le = csvp_line_end(q, lim);
            if (le == lim) {
                if (nulp) {
                    st->nul = 1;
                    *used = (long)(ln - text);
                    return CSVP_OK;
                }
                if (!final || le == ln) {
                    *used = (long)(ln - text);
                    return CSVP_OK;
                }
            }
            st->line++;
        }
        /* past the line end: \n, \r\n or a lone \r (\r\n may straddle two blocks) */
        if (le < end && *le == '\r') {
            if (le + 1 == end && !final) {
                st->line--;
                *used = (long)(ln - text);
                return CSVP_OK;
            }
            p = (le + 1 < end && le[1] == '\n') ? le + 2 : le + 1;
        } else {
            p = le < lim ? le + 1 : le;
        }
        st->rows += row;
        *used = (long)(p - text);
        if (p >= lim) {
            if (nulp && p == nulp) st->nul = 1;
            return CSVP_OK;
        }
    }
}

/* Lines in [text, text + len) up to the first NUL: an upper bound of the rows. */
static long csvp_count_lines(const char *text, long len, int *cr_only)
{
    long n = 0, r = 0;
    const char *p = text, *end = text + len;
    while (p < end) {
        const char *q = memchr(p, '\n', (size_t)(end - p));
        if (!q) break;
        n++;
        p = q + 1;
    }
    if (n == 0) {
        for (p = text; p < end; p++)
            if (*p == '\r') r++;
        *cr_only = r > 0;
        return r;
    }
    *cr_only = 0;
    return n;
}

#endif
