/* Host port of the imufuse MCU harness: the same driver as a normal process. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include "imf_port.h"

void imf_port_init(void)
{
}

void imf_port_write(const char *zstr)
{
    (void)fputs(zstr, stdout);
}

void imf_port_exit(int status)
{
    (void)fflush(stdout);
    exit(status);
}

uint32_t imf_port_count_begin(void)
{
    return 0u;
}

uint32_t imf_port_count_end(uint32_t start)
{
    (void)start;
    return 0u;
}
