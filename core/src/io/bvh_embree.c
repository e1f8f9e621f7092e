/* io/bvh_embree.c: placeholder until the module lands. */
typedef int gi__placeholder_bvh_embree;
