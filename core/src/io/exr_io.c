/* io/exr_io.c: placeholder until the module lands. */
typedef int gi__placeholder_exr_io;
