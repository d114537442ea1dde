use ecr::ecr_method;

ecr_method!(r = 2, family = "tc");

fn main() {}
