// Mesh reading and writing: OFF, OBJ, PLY (ascii / binary little-endian, face lists / tristrips).
// The readers take any bytes: every count in a header is checked against the bytes that could
// hold it before anything is allocated, so a hostile header fails with a message instead of an
// allocation of its claimed size (fuzzed by tests/fuzz).
#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <type_traits>

#include "mesh.hpp"
#include "sdot/error.hpp"
#include "sdot/input_file.hpp"
#include "sdot/output_file.hpp"

namespace sphparam {
namespace {

std::string read_file(const std::string& path) {
  try {
    sdot::require_regular_file(path);
  } catch (const sdot::InputError& e) {
    throw FileError(e.what());
  }
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw FileError(path + ": cannot open for reading (" + std::strerror(errno) + ")");
  // Straight into a string of the file's size: through a string stream the bytes were copied
  // twice, each copy a first touch of fresh pages (igea_134k Loop-subdivided twice, 239 MB, read
  // and parsed in a new process: 1.33-1.67 s -> 1.09-1.21 s). A regular file (checked above): its
  // size is known; a file that shrinks meanwhile gives what was read.
  const std::streamoff size = in.tellg();
  std::string bytes(size > 0 ? static_cast<std::size_t>(size) : 0, '\0');
  in.seekg(0);
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  bytes.resize(static_cast<std::size_t>(in.gcount()));
  if (in.bad()) throw FileError(path + ": cannot read (" + std::strerror(errno) + ")");
  return bytes;
}

/// The C locale's whitespace, without a std::isspace call per character (igea_134k's 10 MB OFF:
/// reading 0.060–0.084 → 0.044–0.048 s).
inline bool is_space(char c) {
  return c == ' ' || c == '\n' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

/// The text after a UTF-8 byte order mark, which some Windows editors put in front of text files.
std::size_t after_byte_order_mark(std::string_view text) {
  return text.substr(0, 3) == "\xEF\xBB\xBF" ? 3 : 0;
}

/// 1-based line number of byte `position` (only computed for error messages).
std::size_t line_of(std::string_view text, std::size_t position) {
  position = std::min(position, text.size());
  return 1 +
         static_cast<std::size_t>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(position), '\n'));
}

template <class T>
bool parse_number(std::string_view t, T& value) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);  // accepted by strtod, not by from_chars
  const auto [end, error] = std::from_chars(t.data(), t.data() + t.size(), value);
  return error == std::errc() && end == t.data() + t.size() && !t.empty();
}

template <class What>
std::string describe(const What& what) {
  if constexpr (std::is_invocable_v<const What&>)
    return what();
  else
    return std::string(what);
}

/// Whitespace tokenizer over a buffer that skips '#' comments (OFF).
class Tokens {
 public:
  Tokens(std::string_view text, std::size_t pos, std::string name, bool comments)
      : s_(text), pos_(pos), name_(std::move(name)), comments_(comments) {}
  bool next(std::string_view& token) {
    skip_space();
    if (pos_ >= s_.size()) return false;
    const std::size_t start = pos_;
    while (pos_ < s_.size() && !is_space(s_[pos_]) && !(comments_ && s_[pos_] == '#')) ++pos_;
    token = s_.substr(start, pos_ - start);
    return true;
  }
  // `what` names the token in error messages: a string, or a function that makes it, so that a
  // token read without error costs no allocation (a 120k-vertex OFF: 5 a face otherwise).
  template <class What>
  std::string_view need(const What& what) {
    std::string_view t;
    if (!next(t)) throw error("unexpected end of file while reading " + describe(what));
    return t;
  }
  // std::from_chars: no allocation per token
  template <class What>
  double number(const What& what) {
    const std::string_view t = need(what);
    double v = 0;
    if (!parse_number(t, v))
      throw error("expected a number for " + describe(what) + ", got '" + std::string(t.substr(0, 40)) + "'");
    if (!std::isfinite(v))
      throw error(describe(what) + " has a coordinate that is not a finite number ('" + std::string(t) + "')");
    return v;
  }
  template <class What>
  long long integer(const What& what) {
    const std::string_view t = need(what);
    long long v = 0;
    if (!parse_number(t, v))
      throw error("expected an integer for " + describe(what) + ", got '" + std::string(t) + "'");
    return v;
  }
  /// Skips what is left of the current line (OFF face colours).
  void skip_line() {
    while (pos_ < s_.size() && s_[pos_] != '\n') ++pos_;
  }
  /// True when only whitespace and comments are left.
  bool at_end() {
    skip_space();
    return pos_ >= s_.size();
  }
  [[nodiscard]] std::size_t position() const { return pos_; }
  [[nodiscard]] std::size_t remaining() const { return s_.size() - std::min(pos_, s_.size()); }
  /// A FileError "name:line: message" at the current position.
  [[nodiscard]] FileError error(const std::string& message) const {
    return FileError(name_ + ":" + std::to_string(line_of(s_, pos_)) + ": " + message);
  }

 private:
  void skip_space() {
    for (;;) {
      while (pos_ < s_.size() && is_space(s_[pos_])) ++pos_;
      if (pos_ < s_.size() && comments_ && s_[pos_] == '#') {
        while (pos_ < s_.size() && s_[pos_] != '\n') ++pos_;
        continue;
      }
      return;
    }
  }
  std::string_view s_;
  std::size_t pos_;
  std::string name_;
  bool comments_;
};

/// Whether `count` items of at least `bytes_each` bytes fit in `available` bytes (no overflow).
bool fits(std::uint64_t count, std::uint64_t bytes_each, std::uint64_t available) {
  return bytes_each == 0 ? count <= available : count <= available / bytes_each;
}

void add_polygon(const std::vector<long long>& idx, Mesh& mesh, ReadInfo& info, const std::string& name,
                 std::size_t face_number) {
  if (idx.size() < 3) {
    ++info.short_faces;
    return;
  }
  for (long long i : idx)
    if (i < 0 || i > std::numeric_limits<int>::max())
      throw FileError(name + ": face " + std::to_string(face_number) + " has vertex index " + std::to_string(i) +
                      " out of range");
  if (idx.size() > 3) {
    ++info.polygons;
    info.polygon_triangles += idx.size() - 2;
  }
  for (std::size_t k = 1; k + 1 < idx.size(); ++k)
    mesh.faces.push_back({static_cast<int>(idx[0]), static_cast<int>(idx[k]), static_cast<int>(idx[k + 1])});
}

/// Every vertex has finite coordinates (NaN and ±inf parse as numbers).
void check_finite(const Mesh& mesh, const std::string& name) {
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v)
    if (!mesh.vertices[v].allFinite())
      throw FileError(name + ": vertex " + std::to_string(v) + " has a coordinate that is not a finite number");
}

/// Every face's vertex indices are below the vertex count.
void check_face_indices(const Mesh& mesh, const std::string& name) {
  const long long nv = static_cast<long long>(mesh.vertices.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int i : mesh.faces[f])
      if (i >= nv)
        throw FileError(name + ": triangle " + std::to_string(f) + " has vertex index " + std::to_string(i) +
                        " but there are " + std::to_string(nv) + " vertices");
}

Mesh parse_off(std::string_view text, const std::string& name, ReadInfo& info) {
  Tokens tok(text, after_byte_order_mark(text), name, true);
  if (tok.at_end()) throw FileError(name + ": empty file (expected an OFF header)");
  std::string_view head = tok.need("the OFF header");
  Mesh mesh;
  long long nv = 0, nf = 0;
  if (head.size() >= 3 && head.substr(head.size() - 3) == "OFF") {
    nv = tok.integer("the vertex count");
  } else if (head.substr(0, 3) == "OFF" && parse_number(head.substr(3), nv)) {  // "OFF3485": header glued to the count
  } else {
    throw FileError(name + ": not an OFF file (first token '" + std::string(head.substr(0, 40)) + "')");
  }
  nf = tok.integer("the face count");
  tok.integer("the edge count");
  if (nv < 0 || nf < 0) throw tok.error("negative vertex or face count in the header");
  // A vertex is 3 tokens and a face at least 1, each token a character and a separator.
  const std::uint64_t tokens_left = (tok.remaining() + 1) / 2;
  if (!fits(static_cast<std::uint64_t>(nv), 3, tokens_left) ||
      !fits(static_cast<std::uint64_t>(nf), 1, tokens_left - 3 * static_cast<std::uint64_t>(nv)))
    throw tok.error("the header claims " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                    " faces, more than the file's " + std::to_string(text.size()) + " bytes can hold");
  mesh.vertices.resize(static_cast<std::size_t>(nv));
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v)
    for (int c = 0; c < 3; ++c) mesh.vertices[v][c] = tok.number([v] { return "vertex " + std::to_string(v); });
  std::vector<long long> idx;
  mesh.faces.reserve(static_cast<std::size_t>(nf));
  for (long long f = 0; f < nf; ++f) {
    const auto face = [f] { return "face " + std::to_string(f); };
    const long long n = tok.integer([&] { return face() + " of " + std::to_string(nf); });
    if (n < 0 || !fits(static_cast<std::uint64_t>(n), 2, tok.remaining() + 1))
      throw tok.error(face() + " of " + std::to_string(nf) + " announces " + std::to_string(n) +
                      " vertex indices, more than the rest of the file holds (truncated?)");
    idx.resize(static_cast<std::size_t>(n));
    for (auto& i : idx) i = tok.integer([&] { return "a vertex index of " + face(); });
    tok.skip_line();  // optional colour values
    for (auto i : idx)
      if (i >= nv)
        throw tok.error(face() + " has vertex index " + std::to_string(i) + " but there are " + std::to_string(nv) +
                        " vertices");
    add_polygon(idx, mesh, info, name, static_cast<std::size_t>(f));
  }
  if (!tok.at_end())
    throw tok.error("more data after the " + std::to_string(nf) +
                    " faces the header announces (are the header's counts wrong?)");
  info.format = "off";
  return mesh;
}

Mesh parse_obj(std::string_view text, const std::string& name, ReadInfo& info) {
  Mesh mesh;
  std::size_t line_number = 0, face_number = 0;
  std::vector<long long> idx;
  std::vector<std::pair<std::vector<long long>, std::size_t>> pending;
  std::size_t pos = after_byte_order_mark(text);
  while (pos < text.size()) {
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    const auto where = [&] { return name + ":" + std::to_string(line_number) + ": "; };
    if (line.size() < 2 || !(line[1] == ' ' || line[1] == '\t')) continue;
    Tokens tok(line.substr(2), 0, where(), false);
    if (line[0] == 'v') {
      Vec3 v;
      for (int c = 0; c < 3; ++c) {
        std::string_view t;
        if (!tok.next(t))
          throw FileError(where() + "vertex " + std::to_string(mesh.vertices.size()) + " needs 3 coordinates");
        if (!parse_number(t, v[c]))
          throw FileError(where() + "vertex " + std::to_string(mesh.vertices.size()) + ": expected a number, got '" +
                          std::string(t.substr(0, 40)) + "'");
      }
      if (!v.allFinite())
        throw FileError(where() + "vertex " + std::to_string(mesh.vertices.size()) +
                        " has a coordinate that is not a finite number");
      mesh.vertices.push_back(v);
    } else if (line[0] == 'f') {
      idx.clear();
      std::string_view t;
      while (tok.next(t)) {
        long long i = 0;
        // "v", "v/vt", "v//vn", "v/vt/vn": the vertex index is before the first slash.
        if (!parse_number(t.substr(0, t.find('/')), i) || i == 0)
          throw FileError(where() + "bad vertex index '" + std::string(t.substr(0, 40)) + "' in face " +
                          std::to_string(face_number));
        const long long n = static_cast<long long>(mesh.vertices.size());
        const long long k = i > 0 ? i - 1 : n + i;
        if (k < 0)
          throw FileError(where() + "face " + std::to_string(face_number) + ": relative index " + std::to_string(i) +
                          " refers before the first vertex");
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
        throw FileError(name + ":" + std::to_string(ln) + ": face " + std::to_string(f) + " has vertex index " +
                        std::to_string(i + 1) + " but there are " + std::to_string(nv) + " vertices");
    add_polygon(face, mesh, info, name, f++);
  }
  info.format = "obj";
  return mesh;
}

struct PlyProperty {
  bool list = false;
  std::string type, count_type, name;
  int size = 0, count_size = 0;  ///< bytes in binary files
};
struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
};

int ply_size(const std::string& t, const std::string& where) {
  static const std::map<std::string, int> sizes{{"char", 1},  {"int8", 1},    {"uchar", 1},  {"uint8", 1},
                                                {"short", 2}, {"int16", 2},   {"ushort", 2}, {"uint16", 2},
                                                {"int", 4},   {"int32", 4},   {"uint", 4},   {"uint32", 4},
                                                {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
  auto it = sizes.find(t);
  if (it == sizes.end()) throw FileError(where + "unknown PLY property type '" + t.substr(0, 40) + "'");
  return it->second;
}

bool ply_is_integer(const std::string& t) {
  return t.find("float") == std::string::npos && t != "double";
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

/// A vertex index stored as a PLY value of any type: an integer in int's range (−1 allowed for
/// strip restarts), else a FileError.
long long ply_index(double value, const std::string& name, const std::string& element, std::uint64_t row) {
  if (!(value == std::floor(value) && value >= -1 && value <= std::numeric_limits<int>::max()))
    throw FileError(name + ": " + element + " " + std::to_string(row) + " has vertex index " + std::to_string(value) +
                    ", which is not a valid index");
  return static_cast<long long>(value);
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

Mesh parse_ply(std::string_view data, const std::string& name, ReadInfo& info) {
  data.remove_prefix(after_byte_order_mark(data));
  if (data.empty()) throw FileError(name + ": empty file (expected a PLY header)");
  if (data.substr(0, 3) != "ply") throw FileError(name + ": not a PLY file (no 'ply' magic)");
  const std::size_t eh = data.find("end_header");
  if (eh == std::string::npos) throw FileError(name + ": the PLY header has no end_header (truncated?)");
  std::size_t body = eh + 10;
  if (body < data.size() && data[body] == '\r') ++body;
  if (body < data.size() && data[body] == '\n') ++body;
  std::istringstream header{std::string(data.substr(0, eh))};
  std::string line, format;
  std::vector<PlyElement> elements;
  std::size_t line_number = 0;
  while (std::getline(header, line)) {
    ++line_number;
    const std::string where = name + ":" + std::to_string(line_number) + ": ";
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "format") {
      ls >> format;
    } else if (key == "element") {
      PlyElement e;
      std::string count;
      ls >> e.name >> count;
      long long parsed = -1;
      if (!parse_number(count, parsed) || parsed < 0)
        throw FileError(where + "element '" + e.name.substr(0, 40) + "' needs a count, got '" + count.substr(0, 40) +
                        "'");
      e.count = static_cast<std::uint64_t>(parsed);
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) throw FileError(where + "PLY property before any element");
      PlyProperty p;
      std::string t;
      ls >> t;
      if (t == "list") {
        p.list = true;
        ls >> p.count_type >> p.type >> p.name;
        p.count_size = ply_size(p.count_type, where);
        if (!ply_is_integer(p.count_type))
          throw FileError(where + "a PLY list count must have an integer type, not '" + p.count_type + "'");
      } else {
        p.type = t;
        ls >> p.name;
      }
      p.size = ply_size(p.type, where);
      elements.back().props.push_back(p);
    }
  }
  if (format != "ascii" && format != "binary_little_endian")
    throw FileError(name + ": PLY format '" + format.substr(0, 40) +
                    "' is not supported (ascii or binary_little_endian)");
  const bool ascii = format == "ascii";
  // Every count is checked against the bytes left before anything of its size is allocated: a
  // binary record needs its fixed-size properties and list counts, an ascii one a token each.
  std::uint64_t bytes_left = data.size() - std::min(body, data.size()), least_bytes = 0;
  for (const auto& e : elements) {
    std::uint64_t record = 0;
    for (const auto& p : e.props) record += ascii ? 2 : static_cast<std::uint64_t>(p.list ? p.count_size : p.size);
    if (!fits(e.count, std::max<std::uint64_t>(record, 1), bytes_left + (ascii ? 1 : 0) - least_bytes))
      throw FileError(name + ": the header claims " + std::to_string(e.count) + " elements '" + e.name.substr(0, 40) +
                      "', more than the file's " + std::to_string(data.size()) + " bytes can hold");
    least_bytes += e.count * record;
  }
  Mesh mesh;
  std::size_t pos = body;
  Tokens tok(data, body, name, false);
  auto truncated = [&](const PlyElement& e, std::uint64_t r) {
    return FileError(name + ": PLY body is truncated in " + e.name.substr(0, 40) + " " + std::to_string(r) + " of " +
                     std::to_string(e.count));
  };
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
      if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0) throw FileError(name + ": PLY vertex element lacks x, y or z");
      mesh.vertices.resize(e.count);
      have_vertices = true;
    }
    const std::string what = e.name.substr(0, 40);
    for (std::uint64_t r = 0; r < e.count; ++r) {
      for (std::size_t k = 0; k < e.props.size(); ++k) {
        const auto& p = e.props[k];
        if (!p.list) {
          double v;
          if (ascii) {
            std::string_view t;
            if (!tok.next(t)) throw truncated(e, r);
            if (!parse_number(t, v))
              throw tok.error("expected a number for " + what + " " + std::to_string(r) + ", got '" +
                              std::string(t.substr(0, 40)) + "'");
          } else {
            if (pos + static_cast<std::size_t>(p.size) > data.size()) throw truncated(e, r);
            v = ply_binary_value(data.data() + pos, p.type);
            pos += static_cast<std::size_t>(p.size);
          }
          if (is_vertex)
            for (int c = 0; c < 3; ++c)
              if (xyz[c] == static_cast<int>(k)) mesh.vertices[r][c] = v;
        } else {
          long long n;
          if (ascii) {
            std::string_view t;
            if (!tok.next(t)) throw truncated(e, r);
            if (!parse_number(t, n))
              throw tok.error("expected a list size for " + what + " " + std::to_string(r) + ", got '" +
                              std::string(t.substr(0, 40)) + "'");
          } else {
            if (pos + static_cast<std::size_t>(p.count_size) > data.size()) throw truncated(e, r);
            n = static_cast<long long>(ply_binary_value(data.data() + pos, p.count_type));
            pos += static_cast<std::size_t>(p.count_size);
          }
          const std::uint64_t left =
              ascii ? (tok.remaining() + 1) / 2 : (data.size() - pos) / static_cast<std::size_t>(p.size);
          if (n < 0 || static_cast<std::uint64_t>(n) > left)
            throw FileError(name + ": " + what + " " + std::to_string(r) + " of " + std::to_string(e.count) +
                            " has a list of " + std::to_string(n) +
                            " values, more than the rest of the file holds (truncated?)");
          idx.resize(static_cast<std::size_t>(n));
          for (auto& i : idx) {
            double v;
            if (ascii) {
              std::string_view t;
              if (!tok.next(t)) throw truncated(e, r);
              if (!parse_number(t, v))
                throw tok.error("expected a vertex index in " + what + " " + std::to_string(r) + ", got '" +
                                std::string(t.substr(0, 40)) + "'");
            } else {
              v = ply_binary_value(data.data() + pos, p.type);
              pos += static_cast<std::size_t>(p.size);
            }
            i = ply_index(v, name, what, r);
          }
          if ((e.name == "face" && (p.name == "vertex_indices" || p.name == "vertex_index")) ||
              (e.name == "face" && k == 0)) {
            add_polygon(idx, mesh, info, name, static_cast<std::size_t>(r));
          } else if (e.name == "tristrips") {
            strips_to_faces(idx, mesh);
          }
        }
      }
    }
  }
  if (!have_vertices) throw FileError(name + ": PLY file has no vertex element");
  if (ascii ? !tok.at_end() : pos != data.size())
    throw FileError(name + ": more data after the elements the header announces (are its counts wrong?)");
  info.format = "ply " + format;
  return mesh;
}

// FreeSurfer binary triangle surfaces (lh.pial, lh.white, lh.sphere, ...): the magic bytes
// FF FF FE, a "created by" line ended by two newlines, big-endian int32 vertex and face counts,
// float32 coordinates and int32 triangles. Tags may follow (volume geometry); they are ignored.
constexpr unsigned char freesurfer_magic[3] = {0xFF, 0xFF, 0xFE};

bool has_freesurfer_magic(std::string_view bytes) {
  return bytes.size() >= 3 && std::memcmp(bytes.data(), freesurfer_magic, 3) == 0;
}

std::uint32_t big_endian_u32(const char* p) {
  const auto* b = reinterpret_cast<const unsigned char*>(p);
  return std::uint32_t{b[0]} << 24 | std::uint32_t{b[1]} << 16 | std::uint32_t{b[2]} << 8 | std::uint32_t{b[3]};
}

void append_big_endian_u32(std::string& s, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) s.push_back(static_cast<char>((v >> shift) & 0xFF));
}

Mesh parse_freesurfer(std::string_view data, const std::string& name, ReadInfo& info) {
  if (data.empty()) throw FileError(name + ": empty file (expected a FreeSurfer surface)");
  if (!has_freesurfer_magic(data)) {
    if (data.size() >= 3 && static_cast<unsigned char>(data[0]) == 0xFF &&
        static_cast<unsigned char>(data[1]) == 0xFF && static_cast<unsigned char>(data[2]) == 0xFF)
      throw FileError(name + ": a FreeSurfer quad surface; only triangle surfaces (magic FF FF FE) are read");
    throw FileError(name + ": not a FreeSurfer triangle surface (no magic bytes FF FF FE)");
  }
  // The "created by" line, then one more newline (nibabel reads it the same way).
  std::size_t pos = data.find('\n', 3);
  if (pos == std::string_view::npos) throw FileError(name + ": truncated in the \"created by\" line");
  ++pos;
  if (pos < data.size() && data[pos] == '\n') ++pos;
  if (data.size() - pos < 8) throw FileError(name + ": truncated before the vertex and face counts");
  const std::uint32_t nv = big_endian_u32(data.data() + pos), nf = big_endian_u32(data.data() + pos + 4);
  pos += 8;
  if (nv > static_cast<std::uint32_t>(std::numeric_limits<int>::max()) ||
      nf > static_cast<std::uint32_t>(std::numeric_limits<int>::max()))
    throw FileError(name + ": negative vertex or face count (" + std::to_string(static_cast<std::int32_t>(nv)) + ", " +
                    std::to_string(static_cast<std::int32_t>(nf)) + ")");
  const std::uint64_t need = 12 * std::uint64_t{nv} + 12 * std::uint64_t{nf};
  if (need > data.size() - pos)
    throw FileError(name + ": the header claims " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                    " faces, which need " + std::to_string(need) + " bytes, but " + std::to_string(data.size() - pos) +
                    " follow (truncated?)");
  Mesh mesh;
  mesh.vertices.resize(nv);
  for (auto& v : mesh.vertices)
    for (int c = 0; c < 3; ++c, pos += 4) v[c] = std::bit_cast<float>(big_endian_u32(data.data() + pos));
  mesh.faces.resize(nf);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int c = 0; c < 3; ++c, pos += 4) {
      const auto index = static_cast<std::int32_t>(big_endian_u32(data.data() + pos));
      if (index < 0 || static_cast<std::uint32_t>(index) >= nv)
        throw FileError(name + ": face " + std::to_string(f) + " has vertex index " + std::to_string(index) +
                        " but there are " + std::to_string(nv) + " vertices");
      mesh.faces[f][static_cast<std::size_t>(c)] = index;
    }
  info.format = "freesurfer";
  return mesh;
}

std::string freesurfer_bytes(const Mesh& mesh) {
  std::string s(reinterpret_cast<const char*>(freesurfer_magic), 3);
  s += "created by sdot-sphere-param\n\n";
  if (mesh.vertices.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()) ||
      mesh.faces.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw FileError("too many vertices or faces for a FreeSurfer surface");
  s.reserve(s.size() + 8 + 12 * (mesh.vertices.size() + mesh.faces.size()));
  append_big_endian_u32(s, static_cast<std::uint32_t>(mesh.vertices.size()));
  append_big_endian_u32(s, static_cast<std::uint32_t>(mesh.faces.size()));
  for (const auto& v : mesh.vertices)
    for (int c = 0; c < 3; ++c) append_big_endian_u32(s, std::bit_cast<std::uint32_t>(static_cast<float>(v[c])));
  for (const auto& f : mesh.faces)
    for (int i : f) append_big_endian_u32(s, static_cast<std::uint32_t>(i));
  return s;
}

void write_all(const std::string& path, const std::string& text) {
  try {
    sdot::write_file_atomically(path, text);
  } catch (const sdot::Error& e) {
    throw FileError(e.what());
  }
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

Mesh parse_mesh(std::string_view bytes, const std::string& format, const std::string& name, ReadInfo* info) {
  ReadInfo local;
  ReadInfo& i = info ? *info : local;
  Mesh mesh;
  if (format == "off")
    mesh = parse_off(bytes, name, i);
  else if (format == "obj")
    mesh = parse_obj(bytes, name, i);
  else if (format == "ply")
    mesh = parse_ply(bytes, name, i);
  else if (format == "freesurfer")
    mesh = parse_freesurfer(bytes, name, i);
  else
    throw FileError(name + ": unknown mesh format '" + format + "' (off, obj, ply or freesurfer)");
  check_finite(mesh, name);
  check_face_indices(mesh, name);
  return mesh;
}

std::string mesh_format(const std::string& path) {
  const std::string e = extension(path);
  if (e == "off" || e == "obj" || e == "ply") return e;
  // FreeSurfer names its surfaces lh.pial, rh.white, lh.sphere.reg, ...
  static const char* const freesurfer_names[] = {"pial",
                                                 "white",
                                                 "sphere",
                                                 "inflated",
                                                 "orig",
                                                 "smoothwm",
                                                 "reg",
                                                 "qsphere",
                                                 "midthickness",
                                                 "graymid",
                                                 "inner",
                                                 "outer",
                                                 "thickness_free_surface"};
  for (const char* n : freesurfer_names)
    if (e == n) return "freesurfer";
  const auto slash = path.find_last_of("/\\");
  const std::string base = slash == std::string::npos ? path : path.substr(slash + 1);
  if (base.rfind("lh.", 0) == 0 || base.rfind("rh.", 0) == 0) return "freesurfer";
  return "";
}

Mesh read_mesh(const std::string& path, ReadInfo* info, const std::string& format) {
  std::string chosen = format.empty() ? mesh_format(path) : format;
  const std::string bytes = read_file(path);
  if (chosen.empty() && has_freesurfer_magic(bytes)) chosen = "freesurfer";
  if (chosen.empty())
    throw FileError(path + ": unknown mesh format '." + extension(path) +
                    "' (use .off, .obj, .ply, a FreeSurfer surface, or --format)");
  return parse_mesh(bytes, chosen, path, info);
}

void write_mesh(const std::string& path, const Mesh& mesh, bool ply_ascii, const std::string& format) {
  const std::string e = format.empty() ? mesh_format(path) : format;
  if (e == "freesurfer") return write_all(path, freesurfer_bytes(mesh));
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
    throw FileError(path + ": unknown mesh format '." + extension(path) +
                    "' (use .off, .obj, .ply, a FreeSurfer surface name, or --format)");
  }
  write_all(path, s);
}

}  // namespace sphparam
