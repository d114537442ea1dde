use ecr::ecr_method;

ecr_method!(r = 2.5);

fn main() {}
