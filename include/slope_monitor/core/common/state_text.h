// A solver's state as text, exact to the bit, for keeping it between runs
// (the site's history, deformation/history.h: the adjuster's reference epoch,
// the radio network's reference solution and tracking state).
//
//   StateWriter w("epoch_store", 1);   // kind and format version
//   w.Put(3).Put(0.1).Put("north_ridge").Put(vector);
//   std::string text = w.str();
//   StateReader r(text, "epoch_store", 1);  // InvalidArgument: another kind or version
//   int n = r.Int(); double x = r.Double(); std::string name = r.String();
//
// Numbers are written as C99 hexadecimal floats (%a), so a double read back
// is the double written; strings are length-prefixed (any bytes). A reader
// that runs out of text, or finds a token of another type, throws
// InvalidArgument naming the kind and the position.
#pragma once

#include <cstdint>
#include <sstream>
#include <string>

#include <Eigen/Core>

namespace slope_monitor {

class StateWriter {
 public:
  StateWriter(const std::string& kind, int version);
  StateWriter& Put(double v);
  StateWriter& Put(int64_t v);
  StateWriter& Put(int v) { return Put(static_cast<int64_t>(v)); }
  StateWriter& Put(bool v) { return Put(static_cast<int64_t>(v ? 1 : 0)); }
  StateWriter& Put(const std::string& v);
  StateWriter& Put(const char* v) { return Put(std::string(v)); }
  template <typename Derived>
  StateWriter& Put(const Eigen::MatrixBase<Derived>& m) {
    for (Eigen::Index i = 0; i < m.size(); ++i) Put(static_cast<double>(m(i)));
    return *this;
  }
  std::string str() const { return out_.str(); }

 private:
  std::ostringstream out_;
};

class StateReader {
 public:
  // Throws InvalidArgument when the text is not of `kind` at `version`.
  StateReader(const std::string& text, const std::string& kind, int version);
  double Double();
  int64_t Int64();
  int Int() { return static_cast<int>(Int64()); }
  bool Bool() { return Int64() != 0; }
  std::string String();
  template <typename Derived>
  void Get(Eigen::MatrixBase<Derived>* m) {
    for (Eigen::Index i = 0; i < m->size(); ++i) (*m)(i) = Double();
  }

 private:
  std::string Token(char type);
  std::string text_, kind_;
  size_t pos_ = 0;
};

}  // namespace slope_monitor
