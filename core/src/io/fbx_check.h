/* io/fbx_check.h: what an FBX file must not hold before assimp reads it.
 *
 * assimp 5.2 follows an FBX file's object connections recursively while it
 * builds the node tree, so a connection loop (an object that is its own
 * parent, or two that are each other's) recurses until the stack runs out
 * and the process dies (fuzz_scene: a 414-byte ASCII file). A valid file's
 * connections never loop. gi__fbx_check reads the connections of a binary
 * or ASCII FBX file and refuses a loop, naming an object on it; a file it
 * cannot walk (truncated records) is refused too, since assimp would walk
 * the same bytes. Anything else is left to assimp. Thread-safe; allocates
 * only for the call. */
#ifndef GI_FBX_CHECK_H
#define GI_FBX_CHECK_H

#include "gi/gi_error.h"

gi_result gi__fbx_check(const char *path, gi_error_info *err);

#endif
