/* io/import_assimp.c: placeholder until the module lands. */
typedef int gi__placeholder_import_assimp;
