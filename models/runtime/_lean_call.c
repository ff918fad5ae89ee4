/* The lean one-sample call of a compiled kernel (matrix-factored's and newton-euler's numba cfuncs): a callable that takes exactly the arguments of
 * PreparedModel.inverse_dynamics(q, qd, qdd, check=True, out=None) (or forward_dynamics(q, qd, tau, check, out))
 * and, for check=False, checks in C what memory safety needs and calls the numba cfunc of the kernel with the raw
 * pointers; with check=True (given a validation cfunc and its plan: models/states/validation_pass.py status for one
 * sample) the same, on plain numpy.ndarrays only, once the validation answers 0 (OK). Without out (None or not
 * given) the result is one of the two last results this object made that nothing else refers to any more
 * (reusable(): the caller dropped it), else a new array (numpy's PyArray_NewFromDescr or numpy.empty(dof)). A forward kernel answers a code: 0, its
 * result is taken; anything else (a state near a bound, not finite), the call is declined: a forward kernel writes
 * into scratch memory of this object (the GIL is held throughout) or into the new array, so a declined call has
 * written nothing a caller sees. Every other call (a batch, any layout it does not take, a state the validation
 * refuses) goes to the Python fallback unchanged, having written nothing: PreparedModel validates and names the
 * field. See models/runtime/lean_call.py.
 *
 * What is checked here, on each of q, qd, qdd and out: an instance of numpy.ndarray (or a subclass),
 * one dimension of dof elements, a stride of 8 bytes, the float64 dtype object numpy uses for native
 * doubles; out writable. The ndarray fields are read through numpy's public struct layout
 * (PyArrayObject_fields, unchanged since numpy 1.7 and in numpy 2); models/runtime/lean_call.py checks at run time
 * that this layout reads what numpy reports before using this module. Built by setup.py (optional:
 * without a C compiler the package installs without it and the Python lean path runs). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <structmember.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

typedef struct {
    PyObject_HEAD
    char *data;
    int nd;
    Py_ssize_t *dimensions;
    Py_ssize_t *strides;
    PyObject *base;
    PyObject *descr;
    int flags;
    PyObject *weakreflist;
} ArrayFields;

#define WRITEABLE 0x0400
#define OWNDATA 0x0004
#define C_CONTIGUOUS 0x0001
/* Results made without out that this object keeps, to reuse once nothing else refers to them. */
#define KEPT 2

typedef void (*kernel_t)(double *, double *, double *, double *, double *, long long);
typedef long long (*forward_t)(double *, double *, double *, double *, double *, long long);
typedef long long (*validate_t)(double *, double *, double *, long long *);
/* numpy's PyArray_NewFromDescr, entry 94 of its C-API table (the capsule numpy.core.multiarray._ARRAY_API; the
   entries are numbered once and never renumbered: numpy/_core/include/numpy/__multiarray_api.h). */
typedef PyObject *(*new_from_descr_t)(PyTypeObject *, PyObject *, int, const Py_ssize_t *, const Py_ssize_t *, void *,
                                      int, PyObject *);
#define NEW_FROM_DESCR 94

/* The interface of this module: models/runtime/lean_call.py uses it only where VERSION is the one it knows. */
#define VERSION 5

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    PyObject *fallback;      /* the Python method: every call it does not take */
    PyObject *params;        /* keeps the parameter array alive */
    PyTypeObject *ndarray;   /* numpy.ndarray */
    PyObject *f8;            /* numpy.dtype(numpy.float64) */
    PyObject *plan;          /* the validation's plan (int64), kept alive; NULL: check=True is not taken */
    long long *planp;
    validate_t validate;
    PyObject *empty;         /* numpy.empty: the result where out is None (unless new_from_descr) */
    PyObject *api;           /* numpy's C-API capsule, kept alive; NULL: numpy.empty is called */
    new_from_descr_t new_from_descr;
    PyObject *dof_obj;       /* dof as a Python int, empty's argument */
    double *p;
    kernel_t kernel;         /* an inverse kernel (void), or NULL */
    forward_t forward;       /* a forward kernel (answers 0: done), or NULL */
    double *scratch;         /* a forward kernel's result before it is copied into out */
    Py_ssize_t dof;
    long long n;
    PyObject *kept[KEPT];    /* the last results made without out (NULL: none), see new_result */
    int next;                /* the slot of kept that the next new result takes */
} LeanCall;

static PyObject *str_check, *str_out;

static inline int usable(LeanCall *self, PyObject *a, int writable) {
    if (!PyObject_TypeCheck(a, self->ndarray)) return 0;
    ArrayFields *f = (ArrayFields *)a;
    return f->nd == 1 && f->dimensions[0] == self->dof && f->strides[0] == 8 && f->descr == self->f8
           && (!writable || (f->flags & WRITEABLE));
}

/* Whether out's dof doubles are apart from an input's (both checked by usable: one dimension of dof
   at a stride of 8): the kernel writes out while it reads the inputs, so an out that overlaps one,
   even partly, is passed to the fallback, which refuses it. */
static inline int apart(LeanCall *self, PyObject *a, PyObject *out) {
    char *x = ((ArrayFields *)a)->data, *o = ((ArrayFields *)out)->data;
    Py_ssize_t bytes = 8 * self->dof;
    return o + bytes <= x || x + bytes <= o;
}

/* Whether a kept result can be handed out again: nothing but this object refers to it (no variable, view,
   buffer export or weak reference), it is still a plain writable C-ordered ndarray of dof float64 that owns
   its memory (its flags, shape or dtype may have been changed while the caller held it). */
static inline int reusable(LeanCall *self, PyObject *r) {
    ArrayFields *f = (ArrayFields *)r;
    return Py_REFCNT(r) == 1 && Py_TYPE(r) == self->ndarray && usable(self, r, 1) && !f->weakreflist && !f->base
           && (f->flags & (OWNDATA | C_CONTIGUOUS)) == (OWNDATA | C_CONTIGUOUS);
}

/* The result of a call without out: a kept one that nothing else refers to any more (the caller dropped
   it: a loop that assigns each result to the same name drops the one before at the call after, so two are
   kept), else a new array (numpy.empty(dof)), kept in turn; NULL with an exception set if numpy fails (no
   memory), or NULL without one if it is not what usable() takes (then the call is declined). Reusing one
   saves numpy's allocation and deallocation, a third of a one-sample call without out. */
static PyObject *new_result(LeanCall *self) {
    for (int k = 0; k < KEPT; k++) {
        PyObject *r = self->kept[k];
        if (r && reusable(self, r)) {
            Py_INCREF(r);
            return r;
        }
    }
    PyObject *res;
    if (self->new_from_descr) { /* numpy.empty(dof) without parsing its arguments: one dimension, C order */
        Py_ssize_t dims[1] = {self->dof};
        Py_INCREF(self->f8); /* the descriptor's reference is stolen */
        res = self->new_from_descr(self->ndarray, self->f8, 1, dims, NULL, NULL, 0, NULL);
    } else {
        PyObject *arg = self->dof_obj;
        res = PyObject_Vectorcall(self->empty, &arg, 1, NULL);
    }
    if (res && !usable(self, res, 1)) Py_CLEAR(res);
    if (res) {
        Py_XSETREF(self->kept[self->next], Py_NewRef(res));
        self->next = (self->next + 1) % KEPT;
    }
    return res;
}

#define DATA(a) ((double *)((ArrayFields *)(a))->data)

/* What lean_try answers for a call it does not take (no object: nothing to release). */
static char declined_tag;
#define DECLINED ((PyObject *)&declined_tag)

/* The call (q, qd, qdd[, check[, out]]) with check and out also by name: its result, NULL with an
   exception set (numpy could not allocate), or DECLINED having written nothing a caller sees. */
static PyObject *lean_try(LeanCall *self, PyObject *const *args, Py_ssize_t np_, PyObject *kwnames) {
    PyObject *check = np_ > 3 ? args[3] : NULL, *out = np_ > 4 ? args[4] : NULL;
    int plain = np_ >= 3 && np_ <= 5;
    if (plain && kwnames) {
        Py_ssize_t nk = PyTuple_GET_SIZE(kwnames);
        for (Py_ssize_t k = 0; k < nk && plain; k++) {
            PyObject *name = PyTuple_GET_ITEM(kwnames, k);
            if (name == str_check || (name != str_out && PyUnicode_Compare(name, str_check) == 0)) {
                if (check) plain = 0; else check = args[np_ + k];
            } else if (name == str_out || PyUnicode_Compare(name, str_out) == 0) {
                if (out) plain = 0; else out = args[np_ + k];
            } else {
                plain = 0;
            }
        }
        if (PyErr_Occurred()) PyErr_Clear();
    }
    if (!check) check = Py_True; /* the public call's default (PublicCall passes the caller's arguments as given) */
    int checked = check == Py_True && self->validate;
    int fresh = !out || out == Py_None; /* no out: a new result */
    if (plain && (check == Py_False || checked) && (!fresh || self->empty || self->new_from_descr) && usable(self, args[0], 0)
        && usable(self, args[1], 0) && usable(self, args[2], 0)
        && (fresh
            || (usable(self, out, 1) && apart(self, args[0], out) && apart(self, args[1], out)
                && apart(self, args[2], out)))
        && (!checked
            || (Py_TYPE(args[0]) == self->ndarray && Py_TYPE(args[1]) == self->ndarray
                && Py_TYPE(args[2]) == self->ndarray
                && self->validate(DATA(args[0]), DATA(args[1]), DATA(args[2]), self->planp) == 0))) {
        PyObject *res = fresh ? new_result(self) : out;
        if (!res) return PyErr_Occurred() ? NULL : DECLINED;
        if (self->forward) {
            double *into = fresh ? DATA(res) : self->scratch;
            if (self->forward(self->p, DATA(args[0]), DATA(args[1]), DATA(args[2]), into, self->n) != 0) {
                if (fresh) Py_DECREF(res);
                return DECLINED;
            }
            if (!fresh) memcpy(DATA(out), self->scratch, 8 * self->dof);
        } else {
            self->kernel(self->p, DATA(args[0]), DATA(args[1]), DATA(args[2]), DATA(res), self->n);
        }
        if (!fresh) Py_INCREF(out);
        return res;
    }
    return DECLINED;
}

static PyObject *lean_vectorcall(PyObject *callable, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    PyObject *res = lean_try((LeanCall *)callable, args, PyVectorcall_NARGS(nargsf), kwnames);
    return res == DECLINED ? PyObject_Vectorcall(((LeanCall *)callable)->fallback, args, nargsf, kwnames) : res;
}

static PyObject *lean_new(PyTypeObject *type, PyObject *args, PyObject *kw) {
    static char *names[] = {"fallback", "params", "ndarray", "f8", "kernel", "p", "dof", "n", "plan", "validate",
                            "planp", "empty", "forward", "api", NULL};
    PyObject *fallback, *params, *ndarray, *f8, *plan = NULL, *empty = NULL, *api = NULL;
    unsigned long long kernel, p, validate = 0, planp = 0;
    Py_ssize_t dof;
    long long n;
    int forward = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OOOOKKnL|OKKOpO", names, &fallback, &params, &ndarray, &f8,
                                     &kernel, &p, &dof, &n, &plan, &validate, &planp, &empty, &forward, &api))
        return NULL;
    if (plan == Py_None) plan = NULL;
    if (empty == Py_None) empty = NULL;
    if (api == Py_None) api = NULL;
    void **table = NULL;
    if (api && !(table = (void **)PyCapsule_GetPointer(api, PyCapsule_GetName(api)))) return NULL;
    if (!PyType_Check(ndarray) || !PyCallable_Check(fallback) || !kernel || !p || dof < 1
        || (plan && (!validate || !planp)) || (empty && !PyCallable_Check(empty))) {
        PyErr_SetString(PyExc_ValueError, "LeanCall(fallback, params, ndarray, f8, kernel, p, dof, n[, plan, validate, "
                                          "planp][, empty=numpy.empty][, forward=False])");
        return NULL;
    }
    double *scratch = NULL;
    if (forward && !(scratch = PyMem_Calloc((size_t)dof, sizeof(double)))) return PyErr_NoMemory();
    PyObject *dof_obj = PyLong_FromSsize_t(dof);
    if (!dof_obj) { PyMem_Free(scratch); return NULL; }
    LeanCall *self = (LeanCall *)type->tp_alloc(type, 0);
    if (!self) { PyMem_Free(scratch); Py_DECREF(dof_obj); return NULL; }
    Py_INCREF(fallback); Py_INCREF(params); Py_INCREF(ndarray); Py_INCREF(f8); Py_XINCREF(empty); Py_XINCREF(api);
    self->api = api;
    self->new_from_descr = table ? (new_from_descr_t)table[NEW_FROM_DESCR] : NULL;
    self->fallback = fallback; self->params = params; self->ndarray = (PyTypeObject *)ndarray; self->f8 = f8;
    self->empty = empty; self->dof_obj = dof_obj; self->scratch = scratch;
    self->p = (double *)(uintptr_t)p; self->dof = dof; self->n = n;
    if (forward) self->forward = (forward_t)(uintptr_t)kernel; else self->kernel = (kernel_t)(uintptr_t)kernel;
    Py_XINCREF(plan);
    self->plan = plan; self->validate = plan ? (validate_t)(uintptr_t)validate : NULL;
    self->planp = plan ? (long long *)(uintptr_t)planp : NULL;
    self->vectorcall = lean_vectorcall;
    return (PyObject *)self;
}

static int lean_traverse(LeanCall *self, visitproc visit, void *arg) {
    Py_VISIT(self->fallback); Py_VISIT(self->params); Py_VISIT(self->ndarray); Py_VISIT(self->f8); Py_VISIT(self->plan);
    Py_VISIT(self->empty); Py_VISIT(self->api);
    for (int k = 0; k < KEPT; k++) Py_VISIT(self->kept[k]);
    return 0;
}

static int lean_clear(LeanCall *self) {
    Py_CLEAR(self->fallback); Py_CLEAR(self->params); Py_CLEAR(self->ndarray); Py_CLEAR(self->f8); Py_CLEAR(self->plan);
    Py_CLEAR(self->empty); Py_CLEAR(self->dof_obj); Py_CLEAR(self->api);
    for (int k = 0; k < KEPT; k++) Py_CLEAR(self->kept[k]);
    self->new_from_descr = NULL;
    self->validate = NULL;
    return 0;
}

static void lean_dealloc(LeanCall *self) {
    PyObject_GC_UnTrack(self);
    lean_clear(self);
    PyMem_Free(self->scratch);
    self->scratch = NULL;
    Py_TYPE(self)->tp_free((PyObject *)self);
}

/* probe(a) -> (nd, dim0, stride0, writable, descr is f8, is ndarray, has weak references, owns data,
   C-ordered, base): what this module reads of a. */
static PyObject *lean_probe(LeanCall *self, PyObject *a) {
    if (!PyObject_TypeCheck(a, self->ndarray))
        return Py_BuildValue("(iiiiiiiiiO)", -1, -1, -1, 0, 0, 0, 0, 0, 0, Py_None);
    ArrayFields *f = (ArrayFields *)a;
    return Py_BuildValue("(innNNNNNNO)", f->nd, f->nd > 0 ? f->dimensions[0] : -1, f->nd > 0 ? f->strides[0] : -1,
                         PyBool_FromLong(f->flags & WRITEABLE), PyBool_FromLong(f->descr == self->f8), PyBool_FromLong(1),
                         PyBool_FromLong(f->weakreflist != NULL), PyBool_FromLong(f->flags & OWNDATA),
                         PyBool_FromLong(f->flags & C_CONTIGUOUS), f->base ? f->base : Py_None);
}

/* allocate() -> a new result array as a call without out makes it (None: not one the call takes). */
static PyObject *lean_allocate(LeanCall *self, PyObject *unused) {
    if (!self->empty && !self->new_from_descr) Py_RETURN_NONE;
    PyObject *res = new_result(self);
    if (!res && !PyErr_Occurred()) Py_RETURN_NONE;
    return res;
}

static PyMethodDef lean_methods[] = {
    {"probe", (PyCFunction)lean_probe, METH_O, "what the lean call reads of an array"},
    {"allocate", (PyCFunction)lean_allocate, METH_NOARGS, "a new result array, as a call without out makes it"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject LeanCallType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "exo_bench.models.runtime._lean_call.LeanCall",
    .tp_basicsize = sizeof(LeanCall),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_new = lean_new,
    .tp_dealloc = (destructor)lean_dealloc,
    .tp_traverse = (traverseproc)lean_traverse,
    .tp_clear = (inquiry)lean_clear,
    .tp_call = PyVectorcall_Call,
    .tp_vectorcall_offset = offsetof(LeanCall, vectorcall),
    .tp_methods = lean_methods,
    .tp_doc = "the lean one-sample call of a compiled kernel; see models/runtime/lean_call.py",
};

/* A public call of PreparedModel (inverse_dynamics, forward_dynamics), defined once, in the base class: a method
   descriptor around the Python function that first offers the call to the instance's lean entry (its
   self._entries.<entry>: a LeanCall, which the kernel's entries hold) and calls the function with the same
   arguments where there is none or it declines (lean_try: having written nothing), so the one-sample call
   runs no Python frame. Like a function in a class body: model.f(...) calls it with the instance first,
   nothing bound (Py_TPFLAGS_METHOD_DESCRIPTOR); model.f is a bound method; PreparedModel.f is itself. Its
   __dict__ holds what functools.update_wrapper copies (the function's name, docstring, __wrapped__). */
/* Where a type keeps an attribute that is a slot (an object field at a fixed offset, T_OBJECT_EX): the type
   (compared, never dereferenced) and its version tag when it was looked up. CPython gives a type a new tag
   whenever it or a base changes, and never reuses one, so an equal tag on the same type means the same
   lookup, as in the interpreter's own attribute caches. */
typedef struct {
    PyTypeObject *type;
    unsigned int version;
    Py_ssize_t offset;
} SlotCache;

/* The value of obj's attribute name where its type holds it in a slot, read at the offset (borrowed; NULL:
   the slot is empty): 1; 0 where it is not a slot (the caller asks PyObject_GetAttr); -1 with an error set. */
static int slot_read(SlotCache *c, PyObject *obj, PyObject *name, PyObject **value) {
    PyTypeObject *t = Py_TYPE(obj);
    if (c->type != t || c->version != t->tp_version_tag || !c->version) {
        PyObject *d = PyObject_GetAttr((PyObject *)t, name); /* a slot's member descriptor is its own class attribute */
        if (!d) {
            if (!PyErr_ExceptionMatches(PyExc_AttributeError)) return -1;
            PyErr_Clear();
            return 0;
        }
        int slot = Py_TYPE(d) == &PyMemberDescr_Type && ((PyMemberDescrObject *)d)->d_member->type == T_OBJECT_EX
                   && PyObject_TypeCheck(obj, PyDescr_TYPE(d));
        Py_ssize_t offset = slot ? ((PyMemberDescrObject *)d)->d_member->offset : 0;
        Py_DECREF(d);
        if (!slot) return 0;
        c->type = t;
        c->version = t->tp_version_tag; /* 0 (no tag): looked up again at the next call */
        c->offset = offset;
    }
    *value = *(PyObject **)((char *)obj + c->offset);
    return 1;
}

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    PyObject *function; /* the Python function: every call the lean entry does not take */
    PyObject *entry;    /* the name of the Entries field that holds the lean entry (interned) */
    PyObject *dict;
    SlotCache entries_at, lean_at; /* the model's _entries, the Entries' lean entry: slots of their types */
} PublicCall;

static PyObject *str_entries;

/* The lean entry of the model obj (a new reference), NULL where it has none (nothing set), or NULL with an
   error set. obj._entries.<entry>, read from the slots (PreparedModel's and the Entries dataclass's) where
   they are slots, else by PyObject_GetAttr. */
static PyObject *lean_of(PublicCall *self, PyObject *obj) {
    PyObject *entries, *lean;
    int found = slot_read(&self->entries_at, obj, str_entries, &entries);
    if (found < 0) return NULL;
    if (found) {
        if (!entries) return NULL;
        Py_INCREF(entries);
    } else if (!(entries = PyObject_GetAttr(obj, str_entries))) {
        return NULL;
    }
    found = slot_read(&self->lean_at, entries, self->entry, &lean);
    if (found > 0) {
        Py_XINCREF(lean);
    } else if (found == 0) {
        lean = PyObject_GetAttr(entries, self->entry);
    } else {
        lean = NULL;
    }
    Py_DECREF(entries);
    return lean;
}

static PyObject *public_vectorcall(PyObject *callable, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    PublicCall *self = (PublicCall *)callable;
    Py_ssize_t n = PyVectorcall_NARGS(nargsf);
    if (n >= 1) {
        PyObject *lean = lean_of(self, args[0]);
        if (!lean) {
            if (PyErr_Occurred() && !PyErr_ExceptionMatches(PyExc_AttributeError)) return NULL;
            PyErr_Clear(); /* not a prepared model's (or not yet): the function says what is wrong */
        } else {
            PyObject *res = Py_TYPE(lean) == &LeanCallType ? lean_try((LeanCall *)lean, args + 1, n - 1, kwnames)
                                                          : DECLINED;
            Py_DECREF(lean);
            if (res != DECLINED) return res;
        }
    }
    return PyObject_Vectorcall(self->function, args, nargsf, kwnames);
}

static PyObject *public_get(PyObject *self, PyObject *obj, PyObject *type) {
    if (obj == NULL || obj == Py_None) return Py_NewRef(self);
    return PyMethod_New(self, obj);
}

static PyObject *public_new(PyTypeObject *type, PyObject *args, PyObject *kw) {
    static char *names[] = {"function", "entry", NULL};
    PyObject *function, *entry;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OU", names, &function, &entry)) return NULL;
    if (!PyCallable_Check(function)) {
        PyErr_SetString(PyExc_ValueError, "PublicCall(function, entry): function must be callable");
        return NULL;
    }
    PublicCall *self = (PublicCall *)type->tp_alloc(type, 0);
    if (!self) return NULL;
    Py_INCREF(entry);
    PyUnicode_InternInPlace(&entry);
    self->function = Py_NewRef(function);
    self->entry = entry;
    self->vectorcall = public_vectorcall;
    return (PyObject *)self;
}

static int public_traverse(PublicCall *self, visitproc visit, void *arg) {
    Py_VISIT(self->function); Py_VISIT(self->dict);
    return 0;
}

static int public_clear(PublicCall *self) {
    Py_CLEAR(self->function); Py_CLEAR(self->entry); Py_CLEAR(self->dict);
    return 0;
}

static void public_dealloc(PublicCall *self) {
    PyObject_GC_UnTrack(self);
    public_clear(self);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyGetSetDef public_getset[] = {
    {"__dict__", PyObject_GenericGetDict, PyObject_GenericSetDict, NULL, NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyTypeObject PublicCallType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "exo_bench.models.runtime._lean_call.PublicCall",
    .tp_basicsize = sizeof(PublicCall),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL | Py_TPFLAGS_METHOD_DESCRIPTOR,
    .tp_new = public_new,
    .tp_dealloc = (destructor)public_dealloc,
    .tp_traverse = (traverseproc)public_traverse,
    .tp_clear = (inquiry)public_clear,
    .tp_call = PyVectorcall_Call,
    .tp_vectorcall_offset = offsetof(PublicCall, vectorcall),
    .tp_descr_get = public_get,
    .tp_dictoffset = offsetof(PublicCall, dict),
    .tp_getset = public_getset,
    .tp_doc = "a public call of PreparedModel that offers one sample to the lean entry first; see models/runtime/lean_call.py",
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_lean_call", NULL, -1, NULL};

PyMODINIT_FUNC PyInit__lean_call(void) {
    if (PyType_Ready(&LeanCallType) < 0 || PyType_Ready(&PublicCallType) < 0) return NULL;
    str_check = PyUnicode_InternFromString("check");
    str_out = PyUnicode_InternFromString("out");
    str_entries = PyUnicode_InternFromString("_entries");
    if (!str_check || !str_out || !str_entries) return NULL;
    PyObject *m = PyModule_Create(&module);
    if (!m) return NULL;
    Py_INCREF(&LeanCallType);
    if (PyModule_AddObject(m, "LeanCall", (PyObject *)&LeanCallType) < 0) return NULL;
    Py_INCREF(&PublicCallType);
    if (PyModule_AddObject(m, "PublicCall", (PyObject *)&PublicCallType) < 0) return NULL;
    if (PyModule_AddIntConstant(m, "VERSION", VERSION) < 0) return NULL;
    return m;
}
