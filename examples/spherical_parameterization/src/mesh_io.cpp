// Mesh reading and writing: OFF, OBJ, PLY (ascii / binary little-endian, face lists / tristrips).
#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "mesh.hpp"

namespace sphparam {
namespace {

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(path + ": cannot open for reading (" + std::strerror(errno) + ")");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// The C locale's whitespace, without a std::isspace call per character (igea_134k's 10 MB OFF:
/// reading 0.060–0.084 → 0.044–0.048 s).
inline bool is_space(char c) {
  return c == ' ' || c == '\n' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

/// Whitespace tokenizer over a buffer that skips '#' comments (OFF).
class Tokens {
 public:
  Tokens(const std::string& text, std::size_t pos, std::string path, bool comments)
      : s_(text), pos_(pos), path_(std::move(path)), comments_(comments) {}
  bool next(std::string_view& token) {
    for (;;) {
      while (pos_ < s_.size() && is_space(s_[pos_])) ++pos_;
      if (pos_ >= s_.size()) return false;
      if (comments_ && s_[pos_] == '#') {
        while (pos_ < s_.size() && s_[pos_] != '\n') ++pos_;
        continue;
      }
      break;
    }
    const std::size_t start = pos_;
    while (pos_ < s_.size() && !is_space(s_[pos_]) && !(comments_ && s_[pos_] == '#')) ++pos_;
    token = std::string_view(s_).substr(start, pos_ - start);
    return true;
  }
  std::string_view need(const char* what) {
    std::string_view t;
    if (!next(t)) throw FileError(path_ + ": unexpected end of file while reading " + what);
    return t;
  }
  // std::from_chars: no allocation per token
  double number(const char* what) {
    const std::string_view t = need(what);
    double v = 0;
    if (!parse(t, v)) throw FileError(path_ + ": expected a number for " + what + ", got '" + std::string(t) + "'");
    return v;
  }
  long long integer(const char* what) {
    const std::string_view t = need(what);
    long long v = 0;
    if (!parse(t, v)) throw FileError(path_ + ": expected an integer for " + what + ", got '" + std::string(t) + "'");
    return v;
  }
  [[nodiscard]] std::size_t position() const { return pos_; }

 private:
  template <class T>
  static bool parse(std::string_view t, T& value) {
    if (!t.empty() && t.front() == '+') t.remove_prefix(1);  // accepted by strtod, not by from_chars
    const auto [end, error] = std::from_chars(t.data(), t.data() + t.size(), value);
    return error == std::errc() && end == t.data() + t.size() && !t.empty();
  }
  const std::string& s_;
  std::size_t pos_;
  std::string path_;
  bool comments_;
};

void add_polygon(const std::vector<long long>& idx, Mesh& mesh, ReadInfo& info, const std::string& path,
                 std::size_t face_number) {
  if (idx.size() < 3) {
    ++info.short_faces;
    return;
  }
  for (long long i : idx)
    if (i < 0 || i > std::numeric_limits<int>::max())
      throw FileError(path + ": face " + std::to_string(face_number) + " has vertex index " + std::to_string(i) +
                      " out of range");
  if (idx.size() > 3) {
    ++info.polygons;
    info.polygon_triangles += idx.size() - 2;
  }
  for (std::size_t k = 1; k + 1 < idx.size(); ++k)
    mesh.faces.push_back({static_cast<int>(idx[0]), static_cast<int>(idx[k]), static_cast<int>(idx[k + 1])});
}

Mesh read_off(const std::string& path, ReadInfo& info) {
  const std::string text = read_file(path);
  Tokens tok(text, 0, path, true);
  std::string_view head = tok.need("the OFF header");
  Mesh mesh;
  long long nv = 0, nf = 0;
  if (head.size() >= 3 && head.substr(head.size() - 3) == "OFF") {
    nv = tok.integer("the vertex count");
  } else if (head.substr(0, 3) == "OFF") {  // "OFF3485": header glued to the count
    nv = std::atoll(std::string(head.substr(3)).c_str());
  } else {
    throw FileError(path + ": not an OFF file (first token '" + std::string(head) + "')");
  }
  nf = tok.integer("the face count");
  tok.integer("the edge count");
  if (nv < 0 || nf < 0) throw FileError(path + ": negative vertex or face count");
  mesh.vertices.resize(static_cast<std::size_t>(nv));
  for (auto& v : mesh.vertices)
    for (int c = 0; c < 3; ++c) v[c] = tok.number("a vertex coordinate");
  std::vector<long long> idx;
  mesh.faces.reserve(static_cast<std::size_t>(nf));
  for (long long f = 0; f < nf; ++f) {
    const long long n = tok.integer("a face size");
    if (n < 0) throw FileError(path + ": face " + std::to_string(f) + " has negative size");
    idx.resize(static_cast<std::size_t>(n));
    for (auto& i : idx) i = tok.integer("a face index");
    // skip optional colour values up to the end of the line? OFF colours follow on the same line;
    // they are rare and indistinguishable from the next face in a token stream, so not supported.
    for (auto i : idx)
      if (i >= nv)
        throw FileError(path + ": face " + std::to_string(f) + " has vertex index " + std::to_string(i) +
                        " but there are " + std::to_string(nv) + " vertices");
    add_polygon(idx, mesh, info, path, static_cast<std::size_t>(f));
  }
  info.format = "off";
  return mesh;
}

Mesh read_obj(const std::string& path, ReadInfo& info) {
  std::ifstream in(path);
  if (!in) throw FileError(path + ": cannot open for reading (" + std::strerror(errno) + ")");
  Mesh mesh;
  std::string line;
  std::size_t line_number = 0, face_number = 0;
  std::vector<long long> idx;
  std::vector<std::pair<std::vector<long long>, std::size_t>> pending;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.size() < 2) continue;
    if (line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) {
      Vec3 v;
      const char* p = line.c_str() + 2;
      for (int c = 0; c < 3; ++c) {
        char* end = nullptr;
        v[c] = std::strtod(p, &end);
        if (end == p) throw FileError(path + ":" + std::to_string(line_number) + ": a vertex needs 3 coordinates");
        p = end;
      }
      mesh.vertices.push_back(v);
    } else if (line[0] == 'f' && (line[1] == ' ' || line[1] == '\t')) {
      std::istringstream ss(line.substr(2));
      std::string t;
      idx.clear();
      while (ss >> t) {
        char* end = nullptr;
        const long long i = std::strtoll(t.c_str(), &end, 10);
        if (end == t.c_str() || i == 0)
          throw FileError(path + ":" + std::to_string(line_number) + ": bad face index '" + t + "'");
        const long long n = static_cast<long long>(mesh.vertices.size());
        const long long k = i > 0 ? i - 1 : n + i;
        if (k < 0) throw FileError(path + ":" + std::to_string(line_number) + ": face index '" + t + "' out of range");
        idx.push_back(k);
      }
      pending.emplace_back(idx, line_number);
      ++face_number;
    }
  }
  const long long nv = static_cast<long long>(mesh.vertices.size());
  std::size_t f = 0;
  for (auto& [face, ln] : pending) {
    for (auto i : face)
      if (i >= nv)
        throw FileError(path + ":" + std::to_string(ln) + ": face index " + std::to_string(i + 1) + " but there are " +
                        std::to_string(nv) + " vertices");
    add_polygon(face, mesh, info, path, f++);
  }
  info.format = "obj";
  return mesh;
}

struct PlyProperty {
  bool list = false;
  std::string type, count_type, name;
};
struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> props;
};

int ply_size(const std::string& t, const std::string& path) {
  static const std::map<std::string, int> sizes{{"char", 1},  {"int8", 1},    {"uchar", 1},  {"uint8", 1},
                                                {"short", 2}, {"int16", 2},   {"ushort", 2}, {"uint16", 2},
                                                {"int", 4},   {"int32", 4},   {"uint", 4},   {"uint32", 4},
                                                {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
  auto it = sizes.find(t);
  if (it == sizes.end()) throw FileError(path + ": unknown PLY property type '" + t + "'");
  return it->second;
}

double ply_binary_value(const char* p, const std::string& t) {
  auto load = [p]<class T>(T) {
    T v;
    std::memcpy(&v, p, sizeof v);
    return static_cast<double>(v);
  };
  if (t == "char" || t == "int8") return load(std::int8_t{});
  if (t == "uchar" || t == "uint8") return load(std::uint8_t{});
  if (t == "short" || t == "int16") return load(std::int16_t{});
  if (t == "ushort" || t == "uint16") return load(std::uint16_t{});
  if (t == "int" || t == "int32") return load(std::int32_t{});
  if (t == "uint" || t == "uint32") return load(std::uint32_t{});
  if (t == "float" || t == "float32") return load(float{});
  return load(double{});
}

void strips_to_faces(const std::vector<long long>& idx, Mesh& mesh) {
  std::vector<long long> strip;
  auto flush = [&] {
    for (std::size_t k = 0; k + 2 < strip.size(); ++k) {
      const long long a = strip[k], b = strip[k + 1], c = strip[k + 2];
      if (a == b || b == c || a == c) continue;
      if (k % 2 == 0)
        mesh.faces.push_back({static_cast<int>(a), static_cast<int>(b), static_cast<int>(c)});
      else
        mesh.faces.push_back({static_cast<int>(b), static_cast<int>(a), static_cast<int>(c)});
    }
    strip.clear();
  };
  for (long long i : idx) {
    if (i < 0)
      flush();
    else
      strip.push_back(i);
  }
  flush();
}

Mesh read_ply(const std::string& path, ReadInfo& info) {
  const std::string data = read_file(path);
  if (data.compare(0, 3, "ply") != 0) throw FileError(path + ": not a PLY file (no 'ply' magic)");
  const std::size_t eh = data.find("end_header");
  if (eh == std::string::npos) throw FileError(path + ": PLY header has no end_header");
  std::size_t body = eh + 10;
  if (body < data.size() && data[body] == '\r') ++body;
  if (body < data.size() && data[body] == '\n') ++body;
  std::istringstream header(data.substr(0, eh));
  std::string line, format;
  std::vector<PlyElement> elements;
  while (std::getline(header, line)) {
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "format") {
      ls >> format;
    } else if (key == "element") {
      PlyElement e;
      ls >> e.name >> e.count;
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) throw FileError(path + ": PLY property before any element");
      PlyProperty p;
      std::string t;
      ls >> t;
      if (t == "list") {
        p.list = true;
        ls >> p.count_type >> p.type >> p.name;
        ply_size(p.count_type, path);
      } else {
        p.type = t;
        ls >> p.name;
      }
      ply_size(p.type, path);
      elements.back().props.push_back(p);
    }
  }
  if (format != "ascii" && format != "binary_little_endian")
    throw FileError(path + ": PLY format '" + format + "' is not supported (ascii or binary_little_endian)");
  const bool ascii = format == "ascii";
  Mesh mesh;
  std::size_t pos = body;
  Tokens tok(data, body, path, false);
  std::vector<long long> idx;
  bool have_vertices = false;
  for (const auto& e : elements) {
    int xyz[3] = {-1, -1, -1};
    for (std::size_t k = 0; k < e.props.size(); ++k)
      for (int c = 0; c < 3; ++c)
        if (e.props[k].name == std::string(1, static_cast<char>('x' + c)) && !e.props[k].list)
          xyz[c] = static_cast<int>(k);
    const bool is_vertex = e.name == "vertex";
    if (is_vertex) {
      if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0) throw FileError(path + ": PLY vertex element lacks x, y or z");
      mesh.vertices.resize(e.count);
      have_vertices = true;
    }
    for (std::size_t r = 0; r < e.count; ++r) {
      for (std::size_t k = 0; k < e.props.size(); ++k) {
        const auto& p = e.props[k];
        if (!p.list) {
          double v;
          if (ascii) {
            v = tok.number("a PLY value");
          } else {
            const int sz = ply_size(p.type, path);
            if (pos + static_cast<std::size_t>(sz) > data.size()) throw FileError(path + ": PLY body is truncated");
            v = ply_binary_value(data.data() + pos, p.type);
            pos += static_cast<std::size_t>(sz);
          }
          if (is_vertex)
            for (int c = 0; c < 3; ++c)
              if (xyz[c] == static_cast<int>(k)) mesh.vertices[r][c] = v;
        } else {
          long long n;
          if (ascii) {
            n = tok.integer("a PLY list size");
          } else {
            const int sz = ply_size(p.count_type, path);
            if (pos + static_cast<std::size_t>(sz) > data.size()) throw FileError(path + ": PLY body is truncated");
            n = static_cast<long long>(ply_binary_value(data.data() + pos, p.count_type));
            pos += static_cast<std::size_t>(sz);
          }
          if (n < 0) throw FileError(path + ": negative PLY list size");
          idx.resize(static_cast<std::size_t>(n));
          const int isz = ply_size(p.type, path);
          for (auto& i : idx) {
            if (ascii) {
              i = tok.integer("a PLY list value");
            } else {
              if (pos + static_cast<std::size_t>(isz) > data.size()) throw FileError(path + ": PLY body is truncated");
              i = static_cast<long long>(ply_binary_value(data.data() + pos, p.type));
              pos += static_cast<std::size_t>(isz);
            }
          }
          if ((e.name == "face" && (p.name == "vertex_indices" || p.name == "vertex_index")) ||
              (e.name == "face" && k == 0)) {
            add_polygon(idx, mesh, info, path, r);
          } else if (e.name == "tristrips") {
            strips_to_faces(idx, mesh);
          }
        }
      }
    }
  }
  if (!have_vertices) throw FileError(path + ": PLY file has no vertex element");
  const long long nv = static_cast<long long>(mesh.vertices.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int i : mesh.faces[f])
      if (i >= nv)
        throw FileError(path + ": triangle " + std::to_string(f) + " has vertex index " + std::to_string(i) +
                        " but there are " + std::to_string(nv) + " vertices");
  info.format = "ply " + format;
  return mesh;
}

void write_all(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw FileError(path + ": cannot open for writing (" + std::strerror(errno) + ")");
  out << text;
  if (!out) throw FileError(path + ": write failed");
}

/// The shortest text that reads back as exactly `v` (std::to_chars; several times faster than
/// printf's %.17g, which was most of the writing time).
void append_number(std::string& s, double v) {
  char buf[40];
  const auto end = std::to_chars(buf, buf + sizeof buf, v).ptr;
  s.append(buf, end);
}

void append_integer(std::string& s, long long v) {
  char buf[24];
  const auto end = std::to_chars(buf, buf + sizeof buf, v).ptr;
  s.append(buf, end);
}

/// "x y z\n" and "<prefix>a b c\n" lines of the text formats.
void append_vertex(std::string& s, const Vec3& v) {
  append_number(s, v.x()), s += ' ', append_number(s, v.y()), s += ' ', append_number(s, v.z()), s += '\n';
}
void append_face(std::string& s, const char* prefix, const Face& f, int base) {
  s += prefix;
  append_integer(s, f[0] + base), s += ' ', append_integer(s, f[1] + base), s += ' ', append_integer(s, f[2] + base);
  s += '\n';
}

}  // namespace

std::string extension(const std::string& path) {
  const auto slash = path.find_last_of("/\\");
  const auto dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string e = path.substr(dot + 1);
  for (auto& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

Mesh read_mesh(const std::string& path, ReadInfo* info) {
  ReadInfo local;
  ReadInfo& i = info ? *info : local;
  const std::string e = extension(path);
  if (e == "off") return read_off(path, i);
  if (e == "obj") return read_obj(path, i);
  if (e == "ply") return read_ply(path, i);
  throw FileError(path + ": unknown mesh format '." + e + "' (use .off, .obj or .ply)");
}

void write_mesh(const std::string& path, const Mesh& mesh, bool ply_ascii) {
  const std::string e = extension(path);
  std::string s;
  s.reserve(mesh.vertices.size() * 60 + mesh.faces.size() * 24);
  if (e == "off") {
    s += "OFF\n" + std::to_string(mesh.vertices.size()) + " " + std::to_string(mesh.faces.size()) + " 0\n";
    for (const auto& v : mesh.vertices) append_vertex(s, v);
    for (const auto& f : mesh.faces) append_face(s, "3 ", f, 0);
  } else if (e == "obj") {
    for (const auto& v : mesh.vertices) {
      s += "v ";
      append_vertex(s, v);
    }
    for (const auto& f : mesh.faces) append_face(s, "f ", f, 1);
  } else if (e == "ply") {
    s += "ply\nformat ";
    s += ply_ascii ? "ascii" : "binary_little_endian";
    s += " 1.0\ncomment written by sdot-sphere-param\nelement vertex " + std::to_string(mesh.vertices.size()) +
         "\nproperty double x\nproperty double y\nproperty double z\nelement face " +
         std::to_string(mesh.faces.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
    if (ply_ascii) {
      for (const auto& v : mesh.vertices) append_vertex(s, v);
      for (const auto& f : mesh.faces) append_face(s, "3 ", f, 0);
    } else {
      static_assert(std::endian::native == std::endian::little, "binary PLY writer assumes a little-endian host");
      for (const auto& v : mesh.vertices) {
        double xyz[3] = {v.x(), v.y(), v.z()};
        s.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
      }
      for (const auto& f : mesh.faces) {
        const unsigned char n = 3;
        s.push_back(static_cast<char>(n));
        std::int32_t idx[3] = {f[0], f[1], f[2]};
        s.append(reinterpret_cast<const char*>(idx), sizeof idx);
      }
    }
  } else {
    throw FileError(path + ": unknown mesh format '." + e + "' (use .off, .obj or .ply)");
  }
  write_all(path, s);
}

}  // namespace sphparam
