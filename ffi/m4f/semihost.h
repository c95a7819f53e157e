/* ARM semihosting (QEMU -semihosting-config enable=on). */
#ifndef SEMIHOST_H
#define SEMIHOST_H
int semihost(int op, const void *arg);
void semihost_puts(const char *s);
void semihost_exit(int code);
#endif
