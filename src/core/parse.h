/* Strict parsing of numbers given on command lines (every command and the
 * service use these, so an option's value means the same everywhere): the
 * whole string must be one finite number. */
#ifndef CV_CORE_PARSE_H
#define CV_CORE_PARSE_H

/* 0 on success, -1 otherwise (empty, trailing text, NaN/Inf, overflow). */
int cv_parse_double(const char *s, double *out);
/* An integer in [lo, hi]; 0 on success, -1 otherwise. */
int cv_parse_int(const char *s, int lo, int hi, int *out);
/* A duration in seconds: a number ("0.0333") or a fraction of two numbers
 * ("1/30", "1001/30000"; the divisor not 0): the form --dt takes in every
 * command.  0 on success, -1 otherwise. */
int cv_parse_seconds(const char *s, double *out);
/* "x,y,z" (exactly n comma-separated finite numbers, no empty field: "5,,0"
 * and ",5,0" are errors) into out; 0 on success. */
int cv_parse_vec(const char *s, int n, double *out);

#endif
