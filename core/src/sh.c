/* sh.c: placeholder until the module lands. */
typedef int gi__placeholder_sh;
