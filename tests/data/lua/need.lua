-- "need" has a required parameter
need{}
