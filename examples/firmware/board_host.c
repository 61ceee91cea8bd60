/* Host board: standard output. */
#include <stdio.h>
#include "board.h"

void board_init(void) {}

void board_write(const char *zstr)
{
    fputs(zstr, stdout);
}

void board_done(void)
{
    fflush(stdout);
}
