// vdb_shim.cpp: the C face of OpenVDB, and the project's only C++ file.
//
// DESIGN. Each extern "C" entry point is a thin try/catch around static C++
// helpers, so no exception crosses into C: std::bad_alloc becomes
// GI_ERR_NOMEM, openvdb::IoError GI_ERR_IO on write, any OpenVDB exception
// GI_ERR_FORMAT on read (the file exists by then, so its content is wrong),
// and anything else GI_ERR_BACKEND with what() in the message. The writer
// turns dense blocks into sparse grids (only values != 0, the background,
// become active), gives each grid the transform described in gi_vdb.h, and
// writes "<path>.tmp.<pid>" before a rename, like the EXR writer (a path that
// is this process's temporary name already is written in place); a write
// the OS refuses (a full disk) is GI_ERR_IO with its reason, the temp file
// removed and nothing renamed (write_checked). Readers
// load the whole file through a stream that throws on a short read (see
// load()), so damaged files fail fast instead of hanging.
// openvdb::initialize() runs once per process under std::call_once.
//
// OpenVDB's headers keep default visibility: hidden copies of its template
// statics (tree type names, grid registry) made openvdb::initialize() crash
// in libopenvdb. What libgi.so exports is decided by core/libgi.map (gi_*
// only), not by the compiler's visibility.
#pragma GCC visibility push(default)
#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>
#pragma GCC visibility pop

#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <mutex>
#include <new>
#include <set>
#include <string>
#include <vector>

extern "C" {
#include "gi/gi_vdb.h"
#include "base/internal.h"
}

namespace {

// A failure with a gi code, thrown by the helpers and caught at the boundary.
struct Fail {
  gi_result code;
  std::string msg;
};

void init_once() {
  static std::once_flag flag;
  std::call_once(flag, [] { openvdb::initialize(); });
}

// Metadata names OpenVDB itself writes on grids; a user key must not clobber them.
bool reserved_grid_key(const std::string &k) {
  using G = openvdb::GridBase;
  for (const char *r : {G::META_GRID_CLASS, G::META_GRID_CREATOR, G::META_GRID_NAME, G::META_SAVE_HALF_FLOAT,
                        G::META_IS_LOCAL_SPACE, G::META_VECTOR_TYPE, G::META_FILE_BBOX_MIN, G::META_FILE_BBOX_MAX,
                        G::META_FILE_COMPRESSION, G::META_FILE_MEM_BYTES, G::META_FILE_VOXEL_COUNT,
                        G::META_FILE_DELAYED_LOAD})
    if (k == r) return true;
  return false;
}

void add_meta(openvdb::MetaMap &map, const gi_vdb_meta *meta, size_t n, const std::string &where, bool is_grid) {
  if (n && !meta) throw Fail{GI_ERR_INVALID_ARG, where + ": metadata array is NULL"};
  for (size_t m = 0; m < n; m++) {
    if (!meta[m].name || !meta[m].name[0])
      throw Fail{GI_ERR_INVALID_ARG, where + ": metadata entry " + std::to_string(m) + " has an empty key"};
    std::string key = meta[m].name;
    if (is_grid && reserved_grid_key(key))
      throw Fail{GI_ERR_INVALID_ARG, where + ": metadata key '" + key + "' is reserved by OpenVDB"};
    if (meta[m].str) {
      map.insertMeta(key, openvdb::StringMetadata(meta[m].str));
    } else {
      if (!std::isfinite(meta[m].num))
        throw Fail{GI_ERR_NONFINITE, where + ": metadata '" + key + "' is not finite"};
      map.insertMeta(key, openvdb::DoubleMetadata(meta[m].num));
    }
  }
}

// The grid's transform (see gi_vdb.h), class and metadata.
void finish_grid(openvdb::GridBase &grid, const char *name, double voxel_size, const double origin[3], bool fog,
                 const gi_vdb_meta *meta, size_t num_meta, const std::string &where) {
  grid.setName(name);
  // Index (i,j,k) is the voxel centre origin + (i+0.5)*voxel_size, in doubles.
  openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(voxel_size);
  double h = 0.5 * voxel_size;
  xform->postTranslate(openvdb::Vec3d(origin[0] + h, origin[1] + h, origin[2] + h));
  grid.setTransform(xform);
  grid.setGridClass(fog ? openvdb::GRID_FOG_VOLUME : openvdb::GRID_UNKNOWN);
  add_meta(grid, meta, num_meta, where, true);
}

// Copies the non-zero voxels of a dense block (x fastest) into a sparse grid.
template <typename GridT, typename Get>
typename GridT::Ptr build_grid(const gi_vdb_grid &g, Get value_at) {
  using V = typename GridT::ValueType;
  typename GridT::Ptr grid = GridT::create(openvdb::zeroVal<V>());
  typename GridT::Accessor acc = grid->getAccessor();
  size_t idx = 0;
  for (int k = 0; k < g.dims[2]; k++)
    for (int j = 0; j < g.dims[1]; j++)
      for (int i = 0; i < g.dims[0]; i++, idx++) {
        V v = value_at(idx);
        if (v != openvdb::zeroVal<V>()) acc.setValue(openvdb::Coord(i, j, k), v);
      }
  // Collapse uniform leaves into tiles: same values, smaller file.
  grid->tree().prune();
  return grid;
}

// A caller's kind as the int it holds: loading a C enum past its values as
// the C++ enum is undefined (UBSan: "not a valid value for type").
int kind_value(const gi_vdb_kind &k) {
  static_assert(sizeof(int) == sizeof(gi_vdb_kind), "a C enum is an int");
  int v;
  std::memcpy(&v, &k, sizeof v);
  return v;
}

openvdb::GridBase::Ptr make_grid(const gi_vdb_grid &g, size_t gi) {
  std::string where = "grid " + std::to_string(gi);
  if (!g.name || !g.name[0]) throw Fail{GI_ERR_INVALID_ARG, where + " has an empty name"};
  where = "grid '" + std::string(g.name) + "'";
  if (kind_value(g.kind) != GI_VDB_FLOAT && kind_value(g.kind) != GI_VDB_VEC3)
    throw Fail{GI_ERR_INVALID_ARG, where + ": unknown kind " + std::to_string(kind_value(g.kind))};
  if (g.dims[0] <= 0 || g.dims[1] <= 0 || g.dims[2] <= 0)
    throw Fail{GI_ERR_INVALID_ARG, where + ": dims must be > 0"};
  if (!g.data) throw Fail{GI_ERR_INVALID_ARG, where + ": no data"};
  if (!(g.voxel_size > 0) || !std::isfinite(g.voxel_size))
    throw Fail{GI_ERR_INVALID_ARG, where + ": voxel_size must be finite and > 0"};
  if (!std::isfinite(g.origin[0]) || !std::isfinite(g.origin[1]) || !std::isfinite(g.origin[2]))
    throw Fail{GI_ERR_NONFINITE, where + ": origin is not finite"};
  size_t comps = g.kind == GI_VDB_VEC3 ? 3 : 1;
  size_t n = (size_t)g.dims[0] * (size_t)g.dims[1] * (size_t)g.dims[2] * comps;
  for (size_t i = 0; i < n; i++)
    if (!std::isfinite(g.data[i]))
      throw Fail{GI_ERR_NONFINITE, where + ": value " + std::to_string(i / comps) + " (x fastest) is not finite"};

  openvdb::GridBase::Ptr grid;
  if (g.kind == GI_VDB_FLOAT)
    grid = build_grid<openvdb::FloatGrid>(g, [&](size_t i) { return g.data[i]; });
  else
    grid = build_grid<openvdb::Vec3SGrid>(
        g, [&](size_t i) { return openvdb::Vec3s(g.data[3 * i], g.data[3 * i + 1], g.data[3 * i + 2]); });

  finish_grid(*grid, g.name, g.voxel_size, g.origin, g.fog_volume != 0, g.meta, g.num_meta, where);
  return grid;
}

// A grid listed voxel by voxel; every listed voxel is switched on.
openvdb::GridBase::Ptr make_sparse_grid(const gi_vdb_sparse &g, size_t gi) {
  std::string where = "grid " + std::to_string(gi);
  if (!g.name || !g.name[0]) throw Fail{GI_ERR_INVALID_ARG, where + " has an empty name"};
  where = "grid '" + std::string(g.name) + "'";
  if (kind_value(g.kind) != GI_VDB_FLOAT && kind_value(g.kind) != GI_VDB_VEC3)
    throw Fail{GI_ERR_INVALID_ARG, where + ": unknown kind " + std::to_string(kind_value(g.kind))};
  if (g.count && (!g.ijk || !g.data)) throw Fail{GI_ERR_INVALID_ARG, where + ": no voxels"};
  if (!(g.voxel_size > 0) || !std::isfinite(g.voxel_size))
    throw Fail{GI_ERR_INVALID_ARG, where + ": voxel_size must be finite and > 0"};
  if (!std::isfinite(g.origin[0]) || !std::isfinite(g.origin[1]) || !std::isfinite(g.origin[2]))
    throw Fail{GI_ERR_NONFINITE, where + ": origin is not finite"};
  size_t comps = g.kind == GI_VDB_VEC3 ? 3 : 1;
  for (size_t i = 0; i < g.count * comps; i++)
    if (!std::isfinite(g.data[i]))
      throw Fail{GI_ERR_NONFINITE, where + ": voxel " + std::to_string(i / comps) + " is not finite"};
  openvdb::GridBase::Ptr out;
  if (g.kind == GI_VDB_FLOAT) {
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.f);
    openvdb::FloatGrid::Accessor acc = grid->getAccessor();
    for (size_t i = 0; i < g.count; i++)
      acc.setValueOn(openvdb::Coord(g.ijk[3 * i], g.ijk[3 * i + 1], g.ijk[3 * i + 2]), g.data[i]);
    out = grid;
  } else {
    openvdb::Vec3SGrid::Ptr grid = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.f));
    openvdb::Vec3SGrid::Accessor acc = grid->getAccessor();
    for (size_t i = 0; i < g.count; i++) {
      const float *v = g.data + 3 * i;
      acc.setValueOn(openvdb::Coord(g.ijk[3 * i], g.ijk[3 * i + 1], g.ijk[3 * i + 2]), openvdb::Vec3s(v[0], v[1], v[2]));
    }
    out = grid;
  }
  finish_grid(*out, g.name, g.voxel_size, g.origin, false, g.meta, g.num_meta, where);
  return out;
}

// OpenVDB's header: magic (8 bytes), file version and library major/minor
// (4 each), the grid-offsets flag (1), then the UUID as 36 ASCII characters.
const long kUuidOffset = 8 + 4 + 4 + 4 + 1;
const size_t kUuidLen = 36;

bool uuid_ok(const char *u) {
  if (std::strlen(u) != kUuidLen) return false;
  for (size_t i = 0; i < kUuidLen; i++) {
    bool dash = i == 8 || i == 13 || i == 18 || i == 23;
    if (dash ? u[i] != '-' : !std::isxdigit((unsigned char)u[i])) return false;
  }
  return true;
}

// Replaces the random UUID OpenVDB wrote with the caller's, after checking
// the bytes there are a UUID (so a format change cannot corrupt a file).
void set_uuid(const std::string &file, const char *uuid) {
  std::FILE *f = std::fopen(file.c_str(), "r+b");
  if (!f) throw Fail{GI_ERR_IO, "cannot reopen '" + file + "' to set its id"};
  char cur[kUuidLen + 1] = {0};
  bool ok = std::fseek(f, kUuidOffset, SEEK_SET) == 0 && std::fread(cur, 1, kUuidLen, f) == kUuidLen &&
            uuid_ok(cur) && std::fseek(f, kUuidOffset, SEEK_SET) == 0 &&
            std::fwrite(uuid, 1, kUuidLen, f) == kUuidLen;
  if (std::fclose(f) != 0) ok = false;
  if (!ok) throw Fail{GI_ERR_IO, "cannot set the file id in '" + file + "'"};
}

// io::File::write never looks at its stream after writing: on a full disk
// it returned normally and left a truncated file, renamed into place as if
// whole. This writes the same bytes (Archive::write, seekable, as File
// does) through a stream whose failures are errors naming the OS reason.
struct CheckedFile : openvdb::io::File {
  explicit CheckedFile(const std::string &name) : File(name) {}
  void put(std::ostream &os, const openvdb::GridCPtrVec &grids, const openvdb::MetaMap &meta) const {
    Archive::write(os, grids, /*seekable=*/true, meta);
  }
};

// "cannot write '<tmp>': <strerror>" from the errno of the call that failed.
[[noreturn]] void write_failed(const std::string &tmp, int e) {
  throw Fail{GI_ERR_IO, "cannot write '" + tmp + "': " + (e ? std::strerror(e) : "write failed")};
}

void write_checked(const std::string &tmp, const openvdb::GridPtrVec &vec, const openvdb::MetaMap &meta) {
  std::ofstream out;
  out.open(tmp, std::ios::out | std::ios::binary | std::ios::trunc);
  if (!out) write_failed(tmp, errno);
  // badbit throws from the write that failed, while errno still says why.
  out.exceptions(std::ios::badbit);
  openvdb::GridCPtrVec grids(vec.begin(), vec.end());
  try {
    errno = 0;
    CheckedFile(tmp).put(out, grids, meta);
    out.flush();
  } catch (const std::ios_base::failure &) {
    write_failed(tmp, errno);
  }
  out.exceptions(std::ios::goodbit);
  errno = 0;
  out.close(); // the last buffered bytes are written here
  if (out.fail()) write_failed(tmp, errno);
}

void write_grids(const char *path, const openvdb::GridPtrVec &vec, const gi_vdb_meta *file_meta,
                 size_t num_file_meta, const char *uuid) {
  if (uuid && !uuid_ok(uuid)) throw Fail{GI_ERR_INVALID_ARG, "file id is not a 36-character UUID"};
  openvdb::MetaMap meta;
  add_meta(meta, file_meta, num_file_meta, "file metadata", false);

  std::string tmp = std::string(path) + ".tmp." + std::to_string((long)getpid());
  /* The caller's own temporary name already (as the EXR writer): in place. */
  std::string own = ".tmp." + std::to_string((long)getpid()), p(path);
  bool in_place = p.size() > own.size() && p.compare(p.size() - own.size(), own.size(), own) == 0;
  if (in_place) tmp = p;
  try {
    write_checked(tmp, vec, meta);
    if (uuid) set_uuid(tmp, uuid);
  } catch (...) {
    std::remove(tmp.c_str());
    throw;
  }
  if (!in_place && std::rename(tmp.c_str(), path) != 0) {
    int e = errno;
    std::remove(tmp.c_str());
    throw Fail{GI_ERR_IO, "cannot rename '" + tmp + "' into place: " + std::strerror(e)};
  }
}

void write_file(const char *path, const gi_vdb_grid *grids, size_t num_grids, const gi_vdb_meta *file_meta,
                size_t num_file_meta) {
  if (!path || !path[0]) throw Fail{GI_ERR_INVALID_ARG, "empty path"};
  if (num_grids == 0 || !grids) throw Fail{GI_ERR_EMPTY, "no grids"};
  openvdb::GridPtrVec vec;
  std::set<std::string> names;
  for (size_t g = 0; g < num_grids; g++) {
    vec.push_back(make_grid(grids[g], g));
    if (!names.insert(grids[g].name).second)
      throw Fail{GI_ERR_INVALID_ARG, "grid name '" + std::string(grids[g].name) + "' given twice"};
  }
  write_grids(path, vec, file_meta, num_file_meta, nullptr);
}

void write_sparse_file(const char *path, const gi_vdb_sparse *grids, size_t num_grids,
                       const gi_vdb_meta *file_meta, size_t num_file_meta, const char *uuid) {
  if (!path || !path[0]) throw Fail{GI_ERR_INVALID_ARG, "empty path"};
  if (num_grids == 0 || !grids) throw Fail{GI_ERR_EMPTY, "no grids"};
  openvdb::GridPtrVec vec;
  std::set<std::string> names;
  for (size_t g = 0; g < num_grids; g++) {
    vec.push_back(make_sparse_grid(grids[g], g));
    if (!names.insert(grids[g].name).second)
      throw Fail{GI_ERR_INVALID_ARG, "grid name '" + std::string(grids[g].name) + "' given twice"};
  }
  write_grids(path, vec, file_meta, num_file_meta, uuid);
}

// A whole file in memory: its grids (with voxels) and its file metadata.
struct Loaded {
  openvdb::GridPtrVecPtr grids;
  openvdb::MetaMap::Ptr meta;
};

// Reads path through an istream that throws on a short read. OpenVDB does
// not check every read, so a truncated file read via io::File can send it
// into multi-GB allocations and minute-long loops; this way it stops at
// the first missing byte. Files are small enough to load whole.
Loaded load(const char *path) {
  struct stat st;
  if (stat(path, &st) != 0) {
    int e = errno;
    throw Fail{e == ENOENT ? GI_ERR_NOT_FOUND : GI_ERR_IO, std::strerror(e)};
  }
  if (!S_ISREG(st.st_mode)) throw Fail{GI_ERR_IO, "not a regular file"};
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    int e = errno;
    throw Fail{GI_ERR_IO, std::string("cannot open: ") + std::strerror(e)};
  }
  in.exceptions(std::ios::failbit | std::ios::badbit);
  openvdb::io::Stream stream(in, /*delayLoad=*/false);
  return Loaded{stream.getGrids(), stream.getMetadata()};
}

openvdb::GridBase::Ptr find_grid(const Loaded &l, const char *name) {
  for (const openvdb::GridBase::Ptr &g : *l.grids)
    if (g->getName() == name) return g;
  throw Fail{GI_ERR_NOT_FOUND, "no grid named '" + std::string(name) + "'"};
}

gi_vdb_kind kind_of(const openvdb::GridBase &grid) {
  if (grid.isType<openvdb::FloatGrid>()) return GI_VDB_FLOAT;
  if (grid.isType<openvdb::Vec3SGrid>()) return GI_VDB_VEC3;
  throw Fail{GI_ERR_FORMAT, "grid '" + grid.getName() + "' has type " + grid.type() +
                                "; only float and vec3s grids are read"};
}

// Double metadata as round-trip text (Metadata::str() keeps only 6 digits).
std::string meta_text(const openvdb::Metadata &m) {
  double d;
  if (m.typeName() == openvdb::DoubleMetadata::staticTypeName())
    d = static_cast<const openvdb::DoubleMetadata &>(m).value();
  else if (m.typeName() == openvdb::FloatMetadata::staticTypeName())
    d = static_cast<const openvdb::FloatMetadata &>(m).value();
  else
    return m.str();
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.15g", d);
  if (std::strtod(buf, nullptr) != d) std::snprintf(buf, sizeof buf, "%.17g", d);
  return buf;
}

// Records code and "VDB file '<path>': <prefix><what>" in err. OpenVDB
// messages can quote bytes of a damaged file, so the text is kept printable
// ASCII. It runs inside catch handlers, where a throw would escape to C:
// a fixed buffer, no allocation.
gi_result fail(gi_error_info *err, gi_result code, const char *path, const char *prefix,
               const char *what) noexcept {
  char text[sizeof err->msg];
  std::snprintf(text, sizeof text, "%s%s", prefix, what ? what : "");
  for (char *c = text; *c; c++)
    if ((unsigned char)*c < 0x20 || (unsigned char)*c > 0x7e) *c = '?';
  return gi__fail(err, code, "VDB file '%s': %s", path ? path : "(null)", text);
}

// Runs fn and maps whatever it throws to a gi_result; `reading` picks the
// code for OpenVDB's exceptions (see the design note).
template <typename Fn>
gi_result guard(const char *path, bool reading, gi_error_info *err, Fn fn) {
  try {
    init_once();
    fn();
    return GI_OK;
  } catch (const Fail &f) {
    return fail(err, f.code, path, "", f.msg.c_str());
  } catch (const std::bad_alloc &) {
    return fail(err, GI_ERR_NOMEM, path, "", "out of memory");
  } catch (const std::ios_base::failure &) {
    return fail(err, reading ? GI_ERR_FORMAT : GI_ERR_IO, path, "",
                reading ? "truncated or damaged (short read)" : "stream error");
  } catch (const openvdb::IoError &e) {
    return fail(err, reading ? GI_ERR_FORMAT : GI_ERR_IO, path, "", e.what());
  } catch (const openvdb::Exception &e) {
    return fail(err, reading ? GI_ERR_FORMAT : GI_ERR_BACKEND, path, "OpenVDB: ", e.what());
  } catch (const std::exception &e) {
    return fail(err, GI_ERR_BACKEND, path, "OpenVDB: ", e.what());
  } catch (...) {
    return fail(err, GI_ERR_BACKEND, path, "", "unknown C++ exception");
  }
}

}  // namespace

extern "C" gi_result gi_vdb_write(const char *path, const gi_vdb_grid *grids, size_t num_grids,
                                  const gi_vdb_meta *file_meta, size_t num_file_meta, gi_error_info *err) {
  return guard(path, false, err, [&] { write_file(path, grids, num_grids, file_meta, num_file_meta); });
}

extern "C" gi_result gi_vdb_write_sparse(const char *path, const gi_vdb_sparse *grids, size_t num_grids,
                                         const gi_vdb_meta *file_meta, size_t num_file_meta, const char *uuid,
                                         gi_error_info *err) {
  return guard(path, false, err,
               [&] { write_sparse_file(path, grids, num_grids, file_meta, num_file_meta, uuid); });
}

extern "C" gi_result gi_vdb_read_info(const char *path, gi_vdb_grid_info *infos, size_t max, size_t *num,
                                      gi_error_info *err) {
  if (num) *num = 0;
  return guard(path, true, err, [&] {
    if (!path || !num || (max && !infos)) throw Fail{GI_ERR_INVALID_ARG, "NULL path, infos or num"};
    Loaded l = load(path);
    size_t n = 0;
    for (const openvdb::GridBase::Ptr &g : *l.grids) {
      gi_vdb_kind kind = kind_of(*g);
      if (n < max) {
        gi_vdb_grid_info &in = infos[n];
        std::memset(&in, 0, sizeof in);
        std::snprintf(in.name, sizeof in.name, "%s", g->getName().c_str());
        in.kind = kind;
        in.voxel_size = g->voxelSize()[0];
        openvdb::Vec3d w = g->indexToWorld(openvdb::Vec3d(0, 0, 0));
        for (int a = 0; a < 3; a++) in.index_to_world[a] = w[a];
        in.active_voxels = (long)g->activeVoxelCount();
        in.is_fog_volume = g->getGridClass() == openvdb::GRID_FOG_VOLUME;
      }
      n++;
    }
    *num = n < max ? n : max;
  });
}

extern "C" gi_result gi_vdb_read_value(const char *path, const char *name, int i, int j, int k, float val[3],
                                       gi_error_info *err) {
  return guard(path, true, err, [&] {
    if (!path || !name || !val) throw Fail{GI_ERR_INVALID_ARG, "NULL path, name or val"};
    openvdb::GridBase::Ptr g = find_grid(load(path), name);
    openvdb::Coord ijk(i, j, k);
    if (kind_of(*g) == GI_VDB_FLOAT) {
      val[0] = openvdb::gridPtrCast<openvdb::FloatGrid>(g)->getConstAccessor().getValue(ijk);
    } else {
      openvdb::Vec3s v = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g)->getConstAccessor().getValue(ijk);
      for (int a = 0; a < 3; a++) val[a] = v[a];
    }
  });
}

extern "C" gi_result gi_vdb_read_meta(const char *path, const char *name, const char *key, char *buf,
                                      size_t bufsize, gi_error_info *err) {
  if (buf && bufsize) buf[0] = '\0';
  return guard(path, true, err, [&] {
    if (!path || !key || !buf || !bufsize) throw Fail{GI_ERR_INVALID_ARG, "NULL path, key or buf"};
    Loaded l = load(path);
    openvdb::MetaMap::Ptr map = name ? find_grid(l, name) : l.meta;
    openvdb::Metadata::Ptr m = (*map)[key];
    if (!m)
      throw Fail{GI_ERR_NOT_FOUND, "no metadata '" + std::string(key) + "' on " +
                                       (name ? "grid '" + std::string(name) + "'" : std::string("the file"))};
    std::string text = meta_text(*m);
    if (text.size() >= bufsize)
      throw Fail{GI_ERR_LIMIT, "metadata '" + std::string(key) + "' needs " + std::to_string(text.size() + 1) +
                                   " bytes, buffer has " + std::to_string(bufsize)};
    std::memcpy(buf, text.c_str(), text.size() + 1);
  });
}

// --- memory figure: grids built in memory only ------------------------------

struct gi_vdb_mem {
  std::vector<openvdb::Vec3fGrid::Ptr> grids;
  std::vector<openvdb::Vec3fGrid::Accessor> acc;
};

extern "C" gi_result gi_vdb_mem_new(int vec3_grids, gi_vdb_mem **out, gi_error_info *err) {
  if (!out) return gi__fail(err, GI_ERR_INVALID_ARG, "gi_vdb_mem_new: out is NULL");
  *out = nullptr;
  if (vec3_grids < 1 || vec3_grids > 64)
    return gi__fail(err, GI_ERR_INVALID_ARG, "gi_vdb_mem_new: vec3_grids must be 1..64, got %d", vec3_grids);
  gi_vdb_mem *m = nullptr;
  gi_result r = guard("(memory)", false, err, [&] {
    m = new gi_vdb_mem;
    for (int g = 0; g < vec3_grids; g++) {
      m->grids.push_back(openvdb::Vec3fGrid::create(openvdb::Vec3f(0.f)));
      m->acc.push_back(m->grids.back()->getAccessor());
    }
  });
  if (r != GI_OK) {
    delete m;
    return r;
  }
  *out = m;
  return GI_OK;
}

extern "C" gi_result gi_vdb_mem_set(gi_vdb_mem *m, int i, int j, int k, const float *vals, gi_error_info *err) {
  if (!m || !vals) return gi__fail(err, GI_ERR_INVALID_ARG, "gi_vdb_mem_set: %s is NULL", m ? "vals" : "m");
  return guard("(memory)", false, err, [&] {
    openvdb::Coord ijk(i, j, k);
    for (size_t g = 0; g < m->acc.size(); g++)
      m->acc[g].setValueOn(ijk, openvdb::Vec3f(vals[3 * g], vals[3 * g + 1], vals[3 * g + 2]));
  });
}

extern "C" void gi_vdb_mem_usage(const gi_vdb_mem *m, size_t *bytes, uint64_t *active) {
  size_t sum = 0;
  uint64_t on = 0;
  if (m) {
    for (const auto &g : m->grids) sum += (size_t)g->memUsage();
    on = m->grids.empty() ? 0 : (uint64_t)m->grids[0]->activeVoxelCount();
  }
  if (bytes) *bytes = sum;
  if (active) *active = on;
}

extern "C" void gi_vdb_mem_free(gi_vdb_mem *m) { delete m; }
