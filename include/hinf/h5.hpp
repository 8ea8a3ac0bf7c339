// Thin RAII layer over the HDF5 C API: datasets and attributes that h5py reads as plain arrays.
// Not the file layouts themselves: those live in src/io (checkpoint, trajectory) and docs/formats.md.
#pragma once
#include <hdf5.h>

#include <cstdint>
#include <string>
#include <vector>

namespace hinf::h5 {

/// Owns one HDF5 identifier (file, group, dataset, dataspace, attribute, property list).
class Handle {
public:
    Handle() = default;
    explicit Handle(hid_t id) : id_(id) {}
    ~Handle() { reset(); }
    Handle(Handle&& o) noexcept : id_(o.id_) { o.id_ = H5I_INVALID_HID; }
    Handle& operator=(Handle&& o) noexcept {
        if (this != &o) {
            reset();
            id_ = o.id_;
            o.id_ = H5I_INVALID_HID;
        }
        return *this;
    }
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;
    hid_t get() const { return id_; }
    bool valid() const { return id_ >= 0; }
    void reset();

private:
    hid_t id_ = H5I_INVALID_HID;
};

/// Creates (truncates) a file. Errors name the path.
Handle create_file(const std::string& path);
/// Opens an existing file; throws hinf::Error naming the path if it is missing or not HDF5.
Handle open_file(const std::string& path, bool writable);
/// Flushes everything written so far to disk.
void flush(hid_t loc);

Handle create_group(hid_t loc, const std::string& name);
Handle open_group(hid_t loc, const std::string& name);
bool exists(hid_t loc, const std::string& path);

/// Writes a dataset of doubles with shape `dims` (row-major). `units` and `meaning` become attributes.
/// With `checksum`, the dataset is chunked and carries HDF5's fletcher32 filter.
void write_doubles(hid_t loc, const std::string& name, const double* data, const std::vector<hsize_t>& dims,
                   const std::string& units = "", const std::string& meaning = "", bool checksum = false);
void write_floats(hid_t loc, const std::string& name, const float* data, const std::vector<hsize_t>& dims,
                  const std::string& units = "", const std::string& meaning = "", bool checksum = false);
void write_int64s(hid_t loc, const std::string& name, const std::int64_t* data, const std::vector<hsize_t>& dims,
                  const std::string& meaning = "");
void write_string(hid_t loc, const std::string& name, const std::string& text, const std::string& meaning = "");

/// Reads a dataset as doubles (any stored numeric type is converted); fills dims.
std::vector<double> read_doubles(hid_t loc, const std::string& name, std::vector<hsize_t>* dims = nullptr);
std::vector<float> read_floats(hid_t loc, const std::string& name, std::vector<hsize_t>* dims = nullptr);
std::vector<std::int64_t> read_int64s(hid_t loc, const std::string& name, std::vector<hsize_t>* dims = nullptr);
std::string read_string(hid_t loc, const std::string& name);

void set_attr(hid_t loc, const std::string& name, double value);
void set_attr(hid_t loc, const std::string& name, std::int64_t value);
void set_attr(hid_t loc, const std::string& name, const std::string& value);
/// Text of any length under `name` of group/file loc: an attribute up to kAttrTextMax bytes (libhdf5 keeps
/// attributes in the object header, 64 kB in all), a string dataset beyond (a large config, a long network
/// description). get_text / has_text read either form.
constexpr std::size_t kAttrTextMax = 16384;
void set_text(hid_t loc, const std::string& name, const std::string& value);
bool has_text(hid_t loc, const std::string& name);
std::string get_text(hid_t loc, const std::string& name);
void set_attr(hid_t loc, const std::string& name, const char* value);
void set_attr(hid_t loc, const std::string& name, const std::vector<double>& value);
bool has_attr(hid_t loc, const std::string& name);
double get_attr_double(hid_t loc, const std::string& name);
std::int64_t get_attr_int(hid_t loc, const std::string& name);
std::string get_attr_string(hid_t loc, const std::string& name);
std::vector<double> get_attr_doubles(hid_t loc, const std::string& name);

/// An extendible, chunked 2-D dataset of doubles [rows x cols] that grows one row at a time.
class RowWriter {
public:
    RowWriter() = default;
    /// Creates the dataset (cols = 1 makes a 1-D dataset).
    static RowWriter create(hid_t loc, const std::string& name, hsize_t cols, const std::string& units,
                            const std::string& meaning);
    /// Opens an existing one and cuts it to `rows` rows (to continue after a checkpoint).
    static RowWriter open_truncated(hid_t loc, const std::string& name, hsize_t rows);
    void append(const double* row);
    hsize_t rows() const { return rows_; }
    hsize_t cols() const { return cols_; }

private:
    Handle dset_;
    hsize_t rows_ = 0, cols_ = 0;
    bool one_d_ = false;
};

}  // namespace hinf::h5
