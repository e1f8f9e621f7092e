"""validate_openapi.py: proto/openapi.yaml is a valid OpenAPI 3.0 document per
the official JSON schema (openapi-spec-validator, a pip package; skips with
77 when it is not installed). check_openapi.py checks the contract itself."""
import sys

try:
    from openapi_spec_validator import validate
    from openapi_spec_validator.readers import read_from_filename
except ImportError:
    print("SKIP: openapi-spec-validator is not installed (pip install openapi-spec-validator)")
    sys.exit(77)
doc, _ = read_from_filename(sys.argv[1])
validate(doc)  # raises, naming the offending path, on an invalid document
print("ok: %s is valid OpenAPI %s" % (sys.argv[1], doc["openapi"]))
