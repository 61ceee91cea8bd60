/* What the example needs from the board: a text output and an end. */
#ifndef BOARD_H
#define BOARD_H

void board_init(void);
void board_write(const char *zstr);
void board_done(void);

#endif /* BOARD_H */
