// gltf_export.cpp: gi_lightmap_write_gltf, the lightmap's triangles as
// binary glTF 2.0 through assimp's exporter.
//
// Design: an aiScene is built by hand (one child node, mesh and material per atlas,
// three unshared corners per triangle so every corner carries its chart's
// UV), positions local to a root node translated to the scene origin (so a
// city far from the world origin keeps float precision in the file), and
// handed to Assimp::Exporter as "glb2". assimp's glTF exporter flips V
// (its scenes use OpenGL's V-up convention, glTF's V runs down), so the
// UVs go in as 1 - v and come out in glTF's convention, matching the EXR's
// first scanline at v = 0. glTF is Y up: a Z-up scene's positions, normals
// and root translation are turned (x, y, z) -> (x, z, -y), a rotation, so
// windings and the normals they give stay outward and Blender or an
// engine shows the scene standing. The file is written under a temporary
// name and renamed; assimp keeps exporter state per Exporter object, but
// its error string is per object too, so concurrent writes are safe. The
// file reads the lightmap through its public accessors only (the core's
// internal headers are C11, with atomics C++ does not share), and its up
// axis through io/gltf_export_up.h.
#include <assimp/Exporter.hpp>
#include <assimp/material.h>
#include <assimp/scene.h>
#include <cstdio>
#include <cstring>
#include <new>
#include <string>
#include <unistd.h>

#include "gi/gi_lightmap.h"
#include "io/gltf_export_up.h"

namespace {

gi_result fail(gi_error_info *err, gi_result code, const std::string &msg) {
  if (err) {
    err->code = code;
    std::snprintf(err->msg, sizeof err->msg, "%s", msg.c_str());
  }
  return code;
}

bool ends_with(const std::string &s, const char *suffix) {
  size_t m = std::strlen(suffix);
  if (s.size() < m) return false;
  for (size_t i = 0; i < m; i++) {
    char c = s[s.size() - m + i];
    if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
    if (c != suffix[i]) return false;
  }
  return true;
}

// A point or direction of the scene in glTF's frame (Y up).
aiVector3D to_gltf(double x, double y, double z, bool z_up) {
  return z_up ? aiVector3D((ai_real)x, (ai_real)z, (ai_real)-y) : aiVector3D((ai_real)x, (ai_real)y, (ai_real)z);
}

// One mesh: the triangles of atlas `atlas`, three corners each.
aiMesh *atlas_mesh(const gi_lightmap *lm, size_t atlas, bool z_up) {
  size_t nt = 0, n = gi_lightmap_num_triangles(lm);
  int chart;
  gi_lightmap_chart ch;
  for (size_t t = 0; t < n; t++)
    if (!gi_lightmap_triangle(lm, t, nullptr, nullptr, nullptr, &chart) && !gi_lightmap_get_chart(lm, (size_t)chart, &ch) &&
        (size_t)ch.atlas == atlas)
      nt++;
  aiMesh *m = new aiMesh();
  m->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
  m->mMaterialIndex = (unsigned)atlas;
  m->mNumVertices = (unsigned)(3 * nt);
  m->mNumFaces = (unsigned)nt;
  m->mVertices = new aiVector3D[3 * nt];
  m->mNormals = new aiVector3D[3 * nt];
  m->mFaces = new aiFace[nt];
  for (int set = 0; set < 2; set++) {
    m->mTextureCoords[set] = new aiVector3D[3 * nt];
    m->mNumUVComponents[set] = 2;
  }
  size_t f = 0;
  for (size_t t = 0; t < n; t++) {
    float uv[6], p[9];
    if (gi_lightmap_triangle(lm, t, nullptr, uv, p, &chart) || gi_lightmap_get_chart(lm, (size_t)chart, &ch) ||
        (size_t)ch.atlas != atlas)
      continue;
    aiVector3D a = to_gltf(p[0], p[1], p[2], z_up), b = to_gltf(p[3], p[4], p[5], z_up),
               c = to_gltf(p[6], p[7], p[8], z_up);
    aiVector3D nrm = ((b - a) ^ (c - a)).Normalize();
    aiFace &face = m->mFaces[f];
    face.mNumIndices = 3;
    face.mIndices = new unsigned[3];
    for (int j = 0; j < 3; j++) {
      unsigned v = (unsigned)(3 * f + j);
      face.mIndices[j] = v;
      m->mVertices[v] = j == 0 ? a : j == 1 ? b : c;
      m->mNormals[v] = nrm;
      for (int set = 0; set < 2; set++) m->mTextureCoords[set][v] = aiVector3D(uv[2 * j], 1.f - uv[2 * j + 1], 0.f);
    }
    f++;
  }
  return m;
}

aiScene *build_scene(const gi_lightmap *lm) {
  aiScene *sc = new aiScene();
  size_t n = gi_lightmap_num_atlases(lm);
  double o[3];
  gi_lightmap_origin(lm, o);
  const bool z_up = gi__lightmap_up(lm) == GI_UP_Z;
  sc->mRootNode = new aiNode("lightmap");
  aiMatrix4x4::Translation(to_gltf(o[0], o[1], o[2], z_up), sc->mRootNode->mTransformation);
  sc->mRootNode->mNumChildren = (unsigned)n;
  sc->mRootNode->mChildren = new aiNode *[n]();
  sc->mNumMeshes = sc->mNumMaterials = (unsigned)n;
  sc->mMeshes = new aiMesh *[n]();
  sc->mMaterials = new aiMaterial *[n]();
  for (size_t i = 0; i < n; i++) {
    char name[32];
    std::snprintf(name, sizeof name, "lightmap.%04zu", i + 1);
    // One child node (one object in Blender) per atlas, so each gets its own image.
    aiNode *child = new aiNode(name);
    child->mParent = sc->mRootNode;
    child->mNumMeshes = 1;
    child->mMeshes = new unsigned[1]{(unsigned)i};
    sc->mRootNode->mChildren[i] = child;
    sc->mMeshes[i] = atlas_mesh(lm, i, z_up);
    sc->mMeshes[i]->mName = aiString(name);
    sc->mMaterials[i] = new aiMaterial();
    aiString s(name);
    sc->mMaterials[i]->AddProperty(&s, AI_MATKEY_NAME);
    aiColor4D white(1, 1, 1, 1);
    sc->mMaterials[i]->AddProperty(&white, 1, AI_MATKEY_BASE_COLOR);
  }
  return sc;
}

}  // namespace

extern "C" gi_result gi_lightmap_write_gltf(const gi_lightmap *lm, const char *path, gi_error_info *err) {
  if (!lm || !path || !*path) return fail(err, GI_ERR_INVALID_ARG, "lightmap: missing lightmap or path");
  if (!ends_with(path, ".glb"))
    return fail(err, GI_ERR_INVALID_ARG, std::string("lightmap: '") + path + "': the glTF output must be a binary .glb file");
  std::string tmp = std::string(path) + ".tmp." + std::to_string((long)getpid());
  aiScene *sc = nullptr;
  try {
    sc = build_scene(lm);
    Assimp::Exporter ex;
    if (ex.Export(sc, "glb2", tmp.c_str()) != AI_SUCCESS) {
      std::string why = ex.GetErrorString();
      delete sc;
      std::remove(tmp.c_str());
      return fail(err, GI_ERR_IO, std::string("lightmap: cannot write '") + path + "': " + why);
    }
  } catch (const std::bad_alloc &) {
    delete sc;
    std::remove(tmp.c_str());
    return fail(err, GI_ERR_NOMEM, std::string("lightmap: out of memory writing '") + path + "'");
  }
  delete sc;
  if (std::rename(tmp.c_str(), path) != 0) {
    std::remove(tmp.c_str());
    return fail(err, GI_ERR_IO, std::string("lightmap: cannot rename the temporary file to '") + path + "'");
  }
  return GI_OK;
}
